#pragma once
// Trajectory files: KITTI poses (12 values per row, optionally preceded by a time column) and
// TUM (time tx ty tz qx qy qz qw). Writers are atomic (temporary file, then rename).
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "osm_graph_slam/common/atomic_file.h"  // writeFileAtomically, used by every writer here

namespace osm_graph_slam {

struct StampedPose {
  double stamp = 0.0;  ///< seconds
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};
using Trajectory = std::vector<StampedPose>;

struct TrajectoryReadResult {
  Trajectory trajectory;
  bool ok = false;
  std::string error;  ///< names the file and the first bad line
};

/// KITTI poses file. Rows of 12 numbers (stamp = row index * 0.1 s) or 13 (time first).
TrajectoryReadResult readKittiPoses(const std::string& path);
/// TUM trajectory file; '#' comments allowed.
TrajectoryReadResult readTumTrajectory(const std::string& path);
/// Picks the reader by content: 8 columns = TUM, 12/13 = KITTI.
TrajectoryReadResult readTrajectory(const std::string& path);

/// Linear/slerp interpolation of a pose list at t [s] (clamped to the ends); false if t lies
/// outside it, or between two poses, farther than max_gap [s].
bool interpolatePose(const Trajectory& poses, double t, double max_gap, Eigen::Isometry3d& out);

bool writeKittiPoses(const std::string& path, const Trajectory& trajectory, bool with_time,
                     std::string* error = nullptr);
bool writeTumTrajectory(const std::string& path, const Trajectory& trajectory,
                        std::string* error = nullptr);

}  // namespace osm_graph_slam
