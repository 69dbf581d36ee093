#include "osm_graph_slam/slam/information.h"

#include <algorithm>
#include <cmath>

namespace osm_graph_slam {

namespace {

/// Translation information with deviation std_along along `motion` and std_across across it.
Eigen::Matrix3d anisotropicInformation(const Eigen::Vector3d& motion, double std_along,
                                       double std_across) {
  const double along = 1.0 / (std_along * std_along);
  const double across = 1.0 / (std_across * std_across);
  const Eigen::Vector3d u = motion.normalized();
  // along·uuᵀ + across·(I − uuᵀ): no need for an explicit orthonormal basis.
  return across * Eigen::Matrix3d::Identity() + (along - across) * u * u.transpose();
}

constexpr double kMinAnisotropicMotion = 0.05;  // [m] below: direction of motion is noise

}  // namespace

Matrix6d odometryInformation(double fitness, const InformationParams& p,
                             const Eigen::Vector3d& motion) {
  const double w =
      fitness < 0.0 ? 0.5 : std::clamp(fitness / std::max(p.max_fitness, 1e-9), 0.0, 1.0);
  const double std_xyz = p.min_std_xyz + w * (p.max_std_xyz - p.min_std_xyz);
  const double std_rot = p.min_std_rot + w * (p.max_std_rot - p.min_std_rot);
  const double std_yaw = p.min_std_yaw + w * (p.max_std_yaw - p.min_std_yaw);
  Matrix6d info = Matrix6d::Zero();
  if (p.lateral_std_ratio != 1.0 && motion.norm() >= kMinAnisotropicMotion)
    info.topLeftCorner<3, 3>() =
        anisotropicInformation(motion, std_xyz, p.lateral_std_ratio * std_xyz);
  else
    info.diagonal().head<3>().setConstant(1.0 / (std_xyz * std_xyz));
  info(3, 3) = info(4, 4) = 1.0 / (std_rot * std_rot);
  info(5, 5) = 1.0 / (std_yaw * std_yaw);
  return info;
}

Eigen::Matrix3d leverInformation(const Eigen::Matrix3d& info_at_point,
                                 const Eigen::Vector2d& lever) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();  // d(point error) / d(x, y, theta)
  J(0, 2) = -lever.y();
  J(1, 2) = lever.x();
  return J.transpose() * info_at_point * J;
}

Eigen::Matrix3d scaledInformation(const Eigen::Matrix3d& matcher_info, double std_xy,
                                  double std_theta, const LineMatcherParams& m) {
  Eigen::Matrix3d info = matcher_info;
  const double sxy = 1.0 / (std_xy * std_xy * m.edge_information_xy);
  const double sth = 1.0 / (std_theta * std_theta * m.edge_information_theta);
  info.topLeftCorner<2, 2>() *= sxy;
  info(2, 2) *= sth;
  info.topRightCorner<2, 1>() *= std::sqrt(sxy * sth);
  info.bottomLeftCorner<1, 2>() *= std::sqrt(sxy * sth);
  return info;
}

}  // namespace osm_graph_slam
