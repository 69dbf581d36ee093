#pragma once
// PCD writing with the project's error convention: false and the reason (errno's text), never an
// exception (PCL's binary writer throws pcl::IOException on a full disk, without the reason).
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// Writes cloud as a binary PCD file, atomically (path.tmp, then rename). An empty cloud is an
/// error: PCL would write a file that its own reader refuses.
bool writePcdAtomically(const std::string& path, const PointCloud& cloud, std::string* error);

/// Reads a PCD file; false with the reason when it is missing, unreadable or holds no point.
bool readPcd(const std::string& path, PointCloud& cloud, std::string* error);

}  // namespace osm_graph_slam
