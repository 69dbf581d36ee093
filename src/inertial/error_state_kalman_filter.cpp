#include "osm_graph_slam/inertial/error_state_kalman_filter.h"

#include <algorithm>
#include <cmath>

namespace osm_graph_slam {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

/// The rotation of a rotation vector (SO(3) exponential).
Eigen::Quaterniond expQuaternion(const Eigen::Vector3d& theta) {
  const double angle = theta.norm();
  if (angle < 1e-12)
    return Eigen::Quaterniond(1.0, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z()).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, theta / angle));
}

/// The rotation vector of a rotation (SO(3) logarithm).
Eigen::Vector3d logQuaternion(const Eigen::Quaterniond& q) {
  const Eigen::AngleAxisd aa(q.normalized());
  double angle = aa.angle();
  Eigen::Vector3d axis = aa.axis();
  if (angle > M_PI) {
    angle = 2.0 * M_PI - angle;
    axis = -axis;
  }
  return axis * angle;
}

}  // namespace

Eigen::Isometry3d EskfState::pose() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = orientation.toRotationMatrix();
  T.translation() = position;
  return T;
}

void ErrorStateKalmanFilter::initialize(double stamp, const Eigen::Isometry3d& pose,
                                        const Eigen::Vector3d& velocity, double position_std,
                                        double orientation_std) {
  state_ = EskfState();
  state_.position = pose.translation();
  state_.orientation = Eigen::Quaterniond(pose.linear()).normalized();
  state_.velocity = velocity;
  P_.setZero();
  P_.block<3, 3>(0, 0).diagonal().setConstant(position_std * position_std);
  P_.block<3, 3>(3, 3).diagonal().setConstant(params_.init_velocity_std *
                                              params_.init_velocity_std);
  P_.block<3, 3>(6, 6).diagonal().setConstant(orientation_std * orientation_std);
  P_.block<3, 3>(9, 9).diagonal().setConstant(params_.init_accel_bias_std *
                                              params_.init_accel_bias_std);
  P_.block<3, 3>(12, 12).diagonal().setConstant(params_.init_gyro_bias_std *
                                                params_.init_gyro_bias_std);
  stamp_ = stamp;
  initialized_ = true;
  have_sample_ = false;
}

void ErrorStateKalmanFilter::step(double dt, const Eigen::Vector3d& accel,
                                  const Eigen::Vector3d& gyro) {
  const Eigen::Matrix3d R = state_.orientation.toRotationMatrix();
  const Eigen::Vector3d a_body = accel - state_.accel_bias;
  const Eigen::Vector3d w_body = gyro - state_.gyro_bias;
  const Eigen::Vector3d a_world = R * a_body + Eigen::Vector3d(0.0, 0.0, -params_.gravity);
  // Nominal kinematics (Solà eq. 260).
  state_.position += state_.velocity * dt + 0.5 * a_world * dt * dt;
  state_.velocity += a_world * dt;
  state_.orientation = (state_.orientation * expQuaternion(w_body * dt)).normalized();
  // Error-state transition (eq. 269) and the perturbation impulses (eq. 270-271).
  Covariance F = Covariance::Identity();
  F.block<3, 3>(0, 3) = Eigen::Matrix3d::Identity() * dt;
  F.block<3, 3>(3, 6) = -R * skew(a_body) * dt;
  F.block<3, 3>(3, 9) = -R * dt;
  F.block<3, 3>(6, 6) = expQuaternion(w_body * dt).toRotationMatrix().transpose();
  F.block<3, 3>(6, 12) = -Eigen::Matrix3d::Identity() * dt;
  Eigen::Matrix<double, 15, 1> q = Eigen::Matrix<double, 15, 1>::Zero();
  q.segment<3>(3).setConstant(params_.accel_noise * params_.accel_noise * dt * dt);
  q.segment<3>(6).setConstant(params_.gyro_noise * params_.gyro_noise * dt * dt);
  q.segment<3>(9).setConstant(params_.accel_bias_walk * params_.accel_bias_walk * dt);
  q.segment<3>(12).setConstant(params_.gyro_bias_walk * params_.gyro_bias_walk * dt);
  P_ = F * P_ * F.transpose();
  P_.diagonal() += q;
}

void ErrorStateKalmanFilter::propagate(double stamp, const Eigen::Vector3d& accel,
                                       const Eigen::Vector3d& gyro) {
  if (!initialized_) return;
  // The previous sample holds until this one (the first one starts the hold).
  const Eigen::Vector3d a = have_sample_ ? last_accel_ : accel;
  const Eigen::Vector3d w = have_sample_ ? last_gyro_ : gyro;
  double remaining = stamp - stamp_;
  while (remaining > 1e-12) {
    const double dt = std::min(remaining, std::max(1e-4, params_.max_step));
    step(dt, a, w);
    remaining -= dt;
  }
  stamp_ = std::max(stamp_, stamp);
  last_accel_ = accel;
  last_gyro_ = gyro;
  have_sample_ = true;
}

Eigen::Isometry3d ErrorStateKalmanFilter::predictPose(double stamp) const {
  ErrorStateKalmanFilter copy = *this;
  if (have_sample_) copy.propagate(stamp, last_accel_, last_gyro_);
  return copy.state_.pose();
}

double ErrorStateKalmanFilter::correctPose(const Eigen::Isometry3d& measured,
                                           const Matrix6d& covariance) {
  if (!initialized_) return 0.0;
  Eigen::Matrix<double, 6, 1> r;
  r.head<3>() = measured.translation() - state_.position;
  r.tail<3>() =
      logQuaternion(state_.orientation.conjugate() * Eigen::Quaterniond(measured.linear()));
  Eigen::Matrix<double, 6, 15> H = Eigen::Matrix<double, 6, 15>::Zero();
  H.block<3, 3>(0, 0).setIdentity();
  H.block<3, 3>(3, 6).setIdentity();
  const Matrix6d S = H * P_ * H.transpose() + covariance;
  const Eigen::LDLT<Matrix6d> S_ldlt(S);
  const Eigen::Matrix<double, 15, 6> K = P_ * H.transpose() * S_ldlt.solve(Matrix6d::Identity());
  const Eigen::Matrix<double, 15, 1> dx = K * r;
  // Joseph form: symmetric and positive semi-definite whatever the gain's round-off (eq. 316).
  const Covariance I_KH = Covariance::Identity() - K * H;
  P_ = I_KH * P_ * I_KH.transpose() + K * covariance * K.transpose();
  inject(dx);
  return r.dot(S_ldlt.solve(r));
}

void ErrorStateKalmanFilter::inject(const Eigen::Matrix<double, 15, 1>& dx) {
  state_.position += dx.segment<3>(0);
  state_.velocity += dx.segment<3>(3);
  state_.orientation = (state_.orientation * expQuaternion(dx.segment<3>(6))).normalized();
  state_.accel_bias += dx.segment<3>(9);
  state_.gyro_bias += dx.segment<3>(12);
  // Reset (eq. 287): the angle error is re-expressed about the corrected orientation.
  Covariance G = Covariance::Identity();
  G.block<3, 3>(6, 6) -= skew(0.5 * dx.segment<3>(6));
  P_ = G * P_ * G.transpose();
  P_ = 0.5 * (P_ + P_.transpose());
}

}  // namespace osm_graph_slam
