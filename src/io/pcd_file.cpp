#include "osm_graph_slam/io/pcd_file.h"

#include <pcl/io/pcd_io.h>

#include <fstream>
#include <type_traits>

#include "osm_graph_slam/io/trajectory_io.h"

namespace osm_graph_slam {
namespace {

/// The binary PCD layout PCL's reader expects: its own header, then the registered fields of each
/// point packed in order (x y z intensity, no padding).
std::string binaryPcd(const PointCloud& cloud) {
  static_assert(std::is_same_v<PointT, pcl::PointXYZI>,
                "binaryPcd writes x y z intensity: change it with the point type");
  std::string bytes = pcl::PCDWriter::generateHeader(cloud) + "DATA binary\n";
  bytes.reserve(bytes.size() + cloud.size() * 4 * sizeof(float));
  for (const auto& p : cloud.points) {
    const float fields[4] = {p.x, p.y, p.z, p.intensity};
    bytes.append(reinterpret_cast<const char*>(fields), sizeof(fields));
  }
  return bytes;
}

}  // namespace

bool writePcdAtomically(const std::string& path, const PointCloud& cloud, std::string* error) {
  // Not pcl::io::savePCDFileBinary: it throws on a full disk without saying why, and does not
  // sync before the rename. The bytes are the same.
  if (cloud.empty()) {
    if (error) *error = "empty cloud for '" + path + "'";
    return false;
  }
  return writeFileAtomically(path, binaryPcd(cloud), error);
}

bool readPcd(const std::string& path, PointCloud& cloud, std::string* error) {
  std::ifstream probe(path);
  if (!probe) {
    if (error) *error = "cannot open " + path;
    return false;
  }
  if (pcl::io::loadPCDFile(path, cloud) != 0) {
    if (error) *error = path + ": not a readable PCD file";
    return false;
  }
  if (cloud.empty()) {
    if (error) *error = path + " holds no point";
    return false;
  }
  return true;
}

}  // namespace osm_graph_slam
