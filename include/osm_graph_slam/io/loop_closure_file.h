#pragma once
// Accepted loop closures as text, one per row: "from_stamp to_stamp tx ty tz qx qy qz qw" (the
// current keyframe's pose in the earlier one's frame, keyframes named by stamp so the file can be
// checked against any ground truth). offline_slam writes loops.txt; evaluate_slam --loops reads it.
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace osm_graph_slam {

struct StampedLoopClosure {
  double from_stamp = 0.0;                                          ///< current keyframe [s]
  double to_stamp = 0.0;                                            ///< earlier keyframe [s]
  Eigen::Isometry3d relative_pose = Eigen::Isometry3d::Identity();  ///< from in to's frame
};

bool writeLoopClosures(const std::string& path, const std::vector<StampedLoopClosure>& loops,
                       std::string* error = nullptr);

struct LoopClosureReadResult {
  std::vector<StampedLoopClosure> loops;
  bool ok = false;
  std::string error;  ///< names the file and the first bad line
};
LoopClosureReadResult readLoopClosures(const std::string& path);

}  // namespace osm_graph_slam
