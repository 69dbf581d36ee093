#pragma once
// SE3 <-> planar (x, y, yaw) conversions, used by the back-end, the markers, the benchmarks and
// the tests; here rather than in graph/ so that none of them has to include the pose graph.
#include <Eigen/Geometry>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

/// (x, y, yaw) of an SE3 pose; yaw = atan2(R10, R00) (the Z of a Z-Y-X Euler decomposition).
Pose2 planarPose(const Eigen::Isometry3d& pose);

/// The SE3 pose of a planar pose: (x, y, 0) and a rotation about z by theta.
Eigen::Isometry3d isometryFromPlanar(const Pose2& pose);

}  // namespace osm_graph_slam
