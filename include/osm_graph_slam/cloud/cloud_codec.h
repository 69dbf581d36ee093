#pragma once
// A compact, checked byte encoding of a point cloud, for keyframe clouds held over hours
// (cloud/cloud_store.h). A PCL PointXYZI takes 32 bytes; here a point takes 8 before deflate:
// x, y, z as int16 steps of `resolution` from the cloud's box centre, intensity as uint16 steps
// between the cloud's smallest and largest. Each plane is byte-shuffled (low bytes, then high
// bytes) so that zlib's deflate finds the runs neighbouring points share.
#include <cstdint>
#include <string>

#include "osm_graph_slam/cloud/cloud_store_params.h"
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// The encoding. Non-finite points are left out (they carry nothing a map or a loop uses); the
/// header keeps frame_id and stamp, the decoded cloud is unorganised and dense.
std::string encodeCloud(const PointCloud& cloud, const CloudCodecParams& params = {});

/// The cloud back; null with *error set (bad magic, version, truncation, checksum, size) for
/// bytes that are not a whole encoding. Each coordinate is within resolution / 2 of the input.
PointCloudPtr decodeCloud(const std::string& bytes, std::string* error = nullptr);

/// The step an encoding used (0 for bytes that are not one).
double encodedResolution(const std::string& bytes);

}  // namespace osm_graph_slam
