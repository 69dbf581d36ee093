#include "osm_graph_slam/graph/information.h"

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

Matrix6d registrationInformation(const Matrix6d& hessian, const Eigen::Isometry3d& relative) {
  // Exp(d) Z = Z Exp(Ad(Z^-1) d): the left perturbation d is Ad(Z) e of the right one e, so
  // the information is Ad(Z)^T H Ad(Z), Ad(Z) = [R, [t]x R; 0, R] for (translation, rotation).
  const Eigen::Matrix3d r = relative.linear();
  const Eigen::Vector3d t = relative.translation();
  Eigen::Matrix3d t_cross;
  t_cross << 0.0, -t.z(), t.y(), t.z(), 0.0, -t.x(), -t.y(), t.x(), 0.0;
  Matrix6d adjoint = Matrix6d::Zero();
  adjoint.topLeftCorner<3, 3>() = r;
  adjoint.topRightCorner<3, 3>() = t_cross * r;
  adjoint.bottomRightCorner<3, 3>() = r;
  Matrix6d info = adjoint.transpose() * hessian * adjoint;
  // The edge's rotation error is half the angle: information per unit of it is 4x (2x across).
  Eigen::Matrix<double, 6, 1> half_angle;
  half_angle << 1.0, 1.0, 1.0, 2.0, 2.0, 2.0;
  info = half_angle.asDiagonal() * info * half_angle.asDiagonal();
  return 0.5 * (info + info.transpose());
}

Eigen::Matrix3d translationMarginal(const Matrix6d& info) {
  const Eigen::LDLT<Eigen::Matrix3d> rotation(info.bottomRightCorner<3, 3>());
  if (rotation.info() != Eigen::Success || !(rotation.vectorD().array() > 0.0).all())
    return Eigen::Matrix3d::Zero();  // a rotation the match did not see: no translation claim
  const Eigen::Matrix3d m =
      info.topLeftCorner<3, 3>() -
      info.topRightCorner<3, 3>() * rotation.solve(info.bottomLeftCorner<3, 3>());
  return 0.5 * (m + m.transpose());
}

Eigen::Matrix3d withDeviationAlong(const Eigen::Matrix3d& info, const Eigen::Vector3d& offset) {
  // Sherman-Morrison: (A^-1 + e e^T)^-1 = A - A e e^T A / (1 + e^T A e), no inverse of A.
  const Eigen::Vector3d a_e = info * offset;
  const double denominator = 1.0 + offset.dot(a_e);
  if (!(denominator > 1.0) || !std::isfinite(denominator)) return info;
  const Eigen::Matrix3d m = info - a_e * a_e.transpose() / denominator;
  return 0.5 * (m + m.transpose());
}

Eigen::Matrix3d leverInformation(const Eigen::Matrix3d& info_at_point,
                                 const Eigen::Vector2d& lever) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();  // d(point error) / d(x, y, theta)
  J(0, 2) = -lever.y();
  J(1, 2) = lever.x();
  return J.transpose() * info_at_point * J;
}

}  // namespace osm_graph_slam
