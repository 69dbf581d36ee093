#include "osm_graph_slam/common/planar_pose.h"

#include <cmath>

namespace osm_graph_slam {

Pose2 planarPose(const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d r = pose.linear();
  return {pose.translation().x(), pose.translation().y(), std::atan2(r(1, 0), r(0, 0))};
}

Eigen::Isometry3d isometryFromPlanar(const Pose2& pose) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(pose.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(pose.x, pose.y, 0.0);
  return t;
}

Pose2 planarPose(const Eigen::Isometry2d& pose) {
  return {pose.translation().x(), pose.translation().y(), yawOf(pose)};
}

Eigen::Isometry2d isometry2dFromPlanar(const Pose2& pose) {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() = pose.rotation();
  T.translation() = pose.translation();
  return T;
}

}  // namespace osm_graph_slam
