#include "osm_graph_slam/localization/map_frames.h"

#include <Eigen/SVD>
#include <limits>

namespace osm_graph_slam {

Eigen::Isometry3d enuToEnu(const EnuConverter& from, const EnuConverter& to) {
  const auto convert = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d g = from.toGeodetic(p);
    return to.toEnu(g.x(), g.y(), g.z());
  };
  const Eigen::Vector3d o = convert(Eigen::Vector3d::Zero());
  Eigen::Matrix3d axes;
  for (int i = 0; i < 3; ++i) axes.col(i) = (convert(100.0 * Eigen::Vector3d::Unit(i)) - o) / 100.0;
  // The nearest rotation to the (almost orthonormal) converted axes.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(axes, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = svd.matrixU() * svd.matrixV().transpose();
  t.translation() = o;
  return t;
}

double mapHeightAt(const MapPackage& map, const Eigen::Vector3d& position) {
  double best = std::numeric_limits<double>::infinity(), z = 0.0;
  for (const auto& kf : map.keyframes) {
    const double d = (kf.pose.translation().head<2>() - position.head<2>()).squaredNorm();
    if (d < best) best = d, z = kf.pose.translation().z();
  }
  return z;
}

Eigen::Isometry3d mapPoseFromXyYaw(const MapPackage& map, double x, double y, double yaw) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(x, y, 0.0);
  pose.translation().z() = mapHeightAt(map, pose.translation());
  return pose;
}

}  // namespace osm_graph_slam
