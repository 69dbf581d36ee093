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

Eigen::Isometry2d fitRigid2d(const std::vector<Eigen::Vector2d>& a,
                             const std::vector<Eigen::Vector2d>& b) {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  if (a.size() < 2 || a.size() != b.size()) return T;
  Eigen::Vector2d ma = Eigen::Vector2d::Zero(), mb = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= double(a.size());
  mb /= double(b.size());
  double sxx = 0.0, sxy = 0.0;  // sum of dot and cross products of the centred pairs
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector2d p = a[i] - ma, q = b[i] - mb;
    sxx += p.dot(q);
    sxy += p.x() * q.y() - p.y() * q.x();
  }
  const double theta = std::atan2(sxy, sxx);
  T.linear() = Eigen::Rotation2Dd(theta).toRotationMatrix();
  T.translation() = mb - T.linear() * ma;
  return T;
}

std::vector<Eigen::Vector2d> spacedPathPoints(const std::vector<Eigen::Vector2d>& path,
                                              double spacing) {
  std::vector<Eigen::Vector2d> kept;
  for (const Eigen::Vector2d& xy : path) {
    bool covered = false;
    for (const Eigen::Vector2d& c : kept) covered = covered || (c - xy).norm() < spacing;
    if (!covered) kept.push_back(xy);
  }
  return kept;
}

}  // namespace osm_graph_slam
