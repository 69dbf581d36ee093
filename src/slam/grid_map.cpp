#include "osm_graph_slam/slam/grid_map.h"

#include <chrono>
#include <map>

namespace osm_graph_slam {
namespace {

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace

GridMapUpdate updateGridMap(OccupancyGrid& grid, const std::vector<KeyframeState>& keyframes) {
  GridMapUpdate update;
  std::map<uint64_t, Eigen::Isometry3d> known_poses;
  for (const KeyframeState& kf : keyframes) {
    if (grid.contains(kf.id)) {
      known_poses.emplace(kf.id, kf.map_pose);
      continue;
    }
    if (kf.cloud.empty()) continue;
    const auto start = std::chrono::steady_clock::now();
    const PointCloudConstPtr cloud = kf.cloud.load();
    if (!cloud) continue;  // unreadable from the store: counted there, shown in its stats
    grid.insertKeyframe(kf.id, kf.map_pose, *cloud, kf.floor);
    update.insert_ms.push_back(msSince(start));
    ++update.inserted;
  }
  const auto start = std::chrono::steady_clock::now();
  update.moved = grid.updatePoses(known_poses);
  update.move_ms = msSince(start);
  return update;
}

}  // namespace osm_graph_slam
