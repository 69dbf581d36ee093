#pragma once
// SE3 <-> planar (x, y, yaw) conversions, used by the back-end, the markers, the benchmarks and
// the tests; here rather than in graph/ so that none of them has to include the pose graph.
#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

/// (x, y, yaw) of an SE3 pose; yaw = atan2(R10, R00) (the Z of a Z-Y-X Euler decomposition).
Pose2 planarPose(const Eigen::Isometry3d& pose);

/// The SE3 pose of a planar pose: (x, y, 0) and a rotation about z by theta.
Eigen::Isometry3d isometryFromPlanar(const Pose2& pose);

/// The same for 2D rigid transforms (radar odometry and its SE2 graph).
Pose2 planarPose(const Eigen::Isometry2d& pose);
Eigen::Isometry2d isometry2dFromPlanar(const Pose2& pose);
/// Rotation angle of a 2D rigid transform, atan2(R10, R00).
inline double yawOf(const Eigen::Isometry2d& T) {
  return std::atan2(T.linear()(1, 0), T.linear()(0, 0));
}

/// Least-squares rigid 2D transform (p_b = T p_a) of paired points; identity if < 2 pairs.
Eigen::Isometry2d fitRigid2d(const std::vector<Eigen::Vector2d>& a,
                             const std::vector<Eigen::Vector2d>& b);

/// Points of `path` in order, each kept unless one kept before lies within `spacing`: every path
/// point ends within `spacing` of one, and a path that comes back reuses its first pass's points.
std::vector<Eigen::Vector2d> spacedPathPoints(const std::vector<Eigen::Vector2d>& path,
                                              double spacing);

}  // namespace osm_graph_slam
