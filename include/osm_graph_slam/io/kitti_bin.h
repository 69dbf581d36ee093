#pragma once
// KITTI Velodyne scans: float32 (x, y, z, reflectance) records, little endian.
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// Reads a KITTI .bin scan into cloud (intensity = reflectance). Returns false and sets error
/// when the file is missing, unreadable or its size is not a multiple of 16 bytes.
bool readKittiBin(const std::string& path, PointCloud& cloud, std::string* error = nullptr);

/// Writes cloud as a KITTI .bin scan, atomically (temporary file, then rename).
bool writeKittiBin(const std::string& path, const PointCloud& cloud, std::string* error = nullptr);

}  // namespace osm_graph_slam
