#pragma once
// Helpers shared by the bag-writing tests (dataset_bag_test, kitti2bag_scans_test): scratch
// folders, files as bytes, and a bag topic's messages with their record times.
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

namespace osm_graph_slam::test {

/// An empty folder at dir (removed first if it exists).
inline std::filesystem::path freshFolder(const std::filesystem::path& dir) {
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline void writeFile(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

inline std::string fileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Every message of a topic, with the time it was recorded at.
template <typename Msg>
std::vector<std::pair<ros::Time, Msg>> readTopic(const std::string& bag_path,
                                                 const std::string& topic) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag, rosbag::TopicQuery(topic));
  std::vector<std::pair<ros::Time, Msg>> out;
  for (const auto& m : view) {
    auto msg = m.instantiate<Msg>();
    if (msg) out.emplace_back(m.getTime(), *msg);
  }
  return out;
}

}  // namespace osm_graph_slam::test
