#include "osm_graph_slam/localization/pose_ukf.h"

#include <Eigen/Cholesky>
#include <cmath>

namespace osm_graph_slam {

Eigen::Quaterniond so3Exp(const Eigen::Vector3d& v) {
  const double angle = v.norm();
  if (angle < 1e-12) {
    Eigen::Quaterniond q(1.0, 0.5 * v.x(), 0.5 * v.y(), 0.5 * v.z());
    return q.normalized();
  }
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle));
}

Eigen::Vector3d so3Log(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // shortest rotation
  const double s = q.vec().norm();
  if (s < 1e-12) return 2.0 * q.vec();
  const double angle = 2.0 * std::atan2(s, q.w());
  return q.vec() * (angle / s);
}

PoseUkf::PoseUkf(const PoseUkfParams& params) : params_(params) {
  const double n = kDim;
  lambda_ = params_.alpha * params_.alpha * (n + params_.kappa) - n;
  wm0_ = lambda_ / (n + lambda_);
  wc0_ = wm0_ + (1.0 - params_.alpha * params_.alpha + params_.beta);
  wi_ = 1.0 / (2.0 * (n + lambda_));
}

void PoseUkf::initialize(const Eigen::Isometry3d& pose, double position_std, double orientation_std,
                         double velocity_std, double rate_std, const Eigen::Vector3d& velocity) {
  state_ = PoseUkfState();
  state_.position = pose.translation();
  state_.orientation = Eigen::Quaterniond(pose.linear()).normalized();
  state_.velocity = velocity;
  cov_.setZero();
  cov_.diagonal().segment<3>(0).setConstant(position_std * position_std);
  cov_.diagonal().segment<3>(3).setConstant(orientation_std * orientation_std);
  cov_.diagonal().segment<3>(6).setConstant(velocity_std * velocity_std);
  cov_.diagonal().segment<3>(9).setConstant(rate_std * rate_std);
  cov_.diagonal().segment<3>(12).setConstant(0.01 * 0.01);
  cov_.diagonal().segment<3>(15).setConstant(params_.accel_bias_std * params_.accel_bias_std);
  initialized_ = true;
}

Eigen::Isometry3d PoseUkf::pose() const {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = state_.orientation.toRotationMatrix();
  pose.translation() = state_.position;
  return pose;
}

PoseUkfState PoseUkf::boxPlus(const PoseUkfState& x, const Vector& d) const {
  PoseUkfState y = x;
  y.position += d.segment<3>(0);
  y.orientation = (x.orientation * so3Exp(d.segment<3>(3))).normalized();
  y.velocity += d.segment<3>(6);
  y.angular_rate += d.segment<3>(9);
  y.gyro_bias += d.segment<3>(12);
  y.accel_bias += d.segment<3>(15);
  return y;
}

PoseUkf::Vector PoseUkf::boxMinus(const PoseUkfState& a, const PoseUkfState& b) const {
  Vector d;
  d.segment<3>(0) = a.position - b.position;
  d.segment<3>(3) = so3Log(b.orientation.conjugate() * a.orientation);
  d.segment<3>(6) = a.velocity - b.velocity;
  d.segment<3>(9) = a.angular_rate - b.angular_rate;
  d.segment<3>(12) = a.gyro_bias - b.gyro_bias;
  d.segment<3>(15) = a.accel_bias - b.accel_bias;
  return d;
}

std::vector<PoseUkfState> PoseUkf::sigmaPoints(const PoseUkfState& mean,
                                               const Covariance& cov) const {
  Covariance scaled = (kDim + lambda_) * 0.5 * (cov + cov.transpose());
  Eigen::LLT<Covariance> llt(scaled);
  double jitter = 1e-12;
  while (llt.info() != Eigen::Success && jitter < 1.0) {
    scaled.diagonal().array() += jitter;
    llt.compute(scaled);
    jitter *= 10.0;
  }
  const Covariance L = llt.matrixL();
  std::vector<PoseUkfState> points;
  points.reserve(2 * kDim + 1);
  points.push_back(mean);
  for (int i = 0; i < kDim; ++i) {
    points.push_back(boxPlus(mean, L.col(i)));
    points.push_back(boxPlus(mean, -L.col(i)));
  }
  return points;
}

PoseUkfState PoseUkf::weightedMean(const std::vector<PoseUkfState>& points) const {
  // Euclidean parts: weighted sums; orientation: Gauss-Newton on SO(3) from the centre point.
  PoseUkfState mean = points.front();
  for (int iteration = 0; iteration < 4; ++iteration) {
    Vector sum = Vector::Zero();
    for (size_t i = 0; i < points.size(); ++i)
      sum += (i == 0 ? wm0_ : wi_) * boxMinus(points[i], mean);
    mean = boxPlus(mean, sum);
    if (sum.segment<3>(3).norm() < 1e-10) break;
  }
  return mean;
}

void PoseUkf::predict(double dt, const std::optional<Eigen::Vector3d>& gyro,
                      const std::optional<Eigen::Vector3d>& accel_in) {
  if (!initialized_ || !(dt > 0.0)) return;
  const bool accel = params_.use_accelerometer && accel_in.has_value();
  const Eigen::Vector3d specific_force = accel ? *accel_in : Eigen::Vector3d::Zero();
  const Eigen::Vector3d gravity(0.0, 0.0, -params_.gravity);
  std::vector<PoseUkfState> points = sigmaPoints(state_, cov_);
  for (auto& x : points) {
    const Eigen::Vector3d rate = gyro ? Eigen::Vector3d(*gyro - x.gyro_bias) : x.angular_rate;
    const Eigen::Quaterniond half = x.orientation * so3Exp(0.5 * dt * rate);
    const Eigen::Quaterniond end = (x.orientation * so3Exp(dt * rate)).normalized();
    if (accel) {
      // Constant map-frame acceleration over the interval, at the mid-interval attitude.
      const Eigen::Vector3d v0 = x.orientation * x.velocity;
      const Eigen::Vector3d a = half * (specific_force - x.accel_bias) + gravity;
      x.position += v0 * dt + 0.5 * dt * dt * a;
      x.velocity = end.conjugate() * (v0 + dt * a);
    } else {
      x.position += half * (x.velocity * dt);  // a car's velocity turns with it
    }
    x.orientation = end;
    if (gyro) x.angular_rate = rate;
  }
  const PoseUkfState mean = weightedMean(points);
  Covariance cov = Covariance::Zero();
  for (size_t i = 0; i < points.size(); ++i) {
    const Vector d = boxMinus(points[i], mean);
    cov += (i == 0 ? wc0_ : wi_) * d * d.transpose();
  }
  const auto sq = [](double v) { return v * v; };
  Vector q = Vector::Zero();
  q.segment<3>(0).setConstant(sq(params_.position_noise) * dt);
  // With a gyro the orientation follows its integrated noise (plus unmodelled motion).
  q.segment<3>(3).setConstant(sq(params_.orientation_noise) * dt +
                              (gyro ? sq(params_.gyro_noise * dt) : 0.0));
  q.segment<3>(6).setConstant(accel ? sq(params_.accel_noise * dt) +
                                          sq(params_.accel_velocity_noise) * dt
                                    : sq(params_.velocity_noise) * dt);
  q.segment<3>(9).setConstant(gyro ? sq(params_.gyro_noise) : sq(params_.angular_rate_noise) * dt);
  q.segment<3>(12).setConstant(sq(params_.gyro_bias_noise) * dt);
  q.segment<3>(15).setConstant(sq(params_.accel_bias_noise) * dt);
  cov.diagonal() += q;
  state_ = mean;
  cov_ = 0.5 * (cov + cov.transpose());
}

void PoseUkf::poseInnovation(const Eigen::Isometry3d& measured, double position_std,
                             double orientation_std, Eigen::Matrix<double, 6, 1>& innovation,
                             Eigen::Matrix<double, 6, 6>& S,
                             Eigen::Matrix<double, kDim, 6>& C) const {
  const std::vector<PoseUkfState> points = sigmaPoints(state_, cov_);
  // Predicted measurement = the sigma points' pose; its mean is the pose part of their mean.
  const PoseUkfState mean = weightedMean(points);
  S.setZero();
  C.setZero();
  for (size_t i = 0; i < points.size(); ++i) {
    const double w = i == 0 ? wc0_ : wi_;
    Eigen::Matrix<double, 6, 1> dz;
    dz.head<3>() = points[i].position - mean.position;
    dz.tail<3>() = so3Log(mean.orientation.conjugate() * points[i].orientation);
    S += w * dz * dz.transpose();
    C += w * boxMinus(points[i], state_) * dz.transpose();
  }
  S.diagonal().head<3>().array() += position_std * position_std;
  S.diagonal().tail<3>().array() += orientation_std * orientation_std;
  innovation.head<3>() = measured.translation() - mean.position;
  innovation.tail<3>() =
      so3Log(mean.orientation.conjugate() * Eigen::Quaterniond(measured.linear()).normalized());
}

double PoseUkf::mahalanobis(const Eigen::Isometry3d& measured, double position_std,
                            double orientation_std) const {
  if (!initialized_) return 0.0;
  Eigen::Matrix<double, 6, 1> y;
  Eigen::Matrix<double, 6, 6> S;
  Eigen::Matrix<double, kDim, 6> C;
  poseInnovation(measured, position_std, orientation_std, y, S, C);
  return y.dot(S.ldlt().solve(y));
}

double PoseUkf::correct(const Eigen::Isometry3d& measured, double position_std,
                        double orientation_std) {
  if (!initialized_) {
    initialize(measured, position_std, orientation_std, 10.0, 1.0);
    return 0.0;
  }
  Eigen::Matrix<double, 6, 1> y;
  Eigen::Matrix<double, 6, 6> S;
  Eigen::Matrix<double, kDim, 6> C;
  poseInnovation(measured, position_std, orientation_std, y, S, C);
  const Eigen::Matrix<double, 6, 6> S_inv = S.inverse();
  const Eigen::Matrix<double, kDim, 6> K = C * S_inv;
  state_ = boxPlus(state_, K * y);
  const Covariance cov = cov_ - K * S * K.transpose();
  cov_ = 0.5 * (cov + cov.transpose());
  return y.dot(S_inv * y);
}

}  // namespace osm_graph_slam
