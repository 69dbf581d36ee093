// The error-state Kalman filter (inertial/): propagation against a known trajectory, bias
// estimation from pose corrections, the Joseph-form covariance and the consistency statistic.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <iostream>
#include <random>

#include "osm_graph_slam/inertial/error_state_kalman_filter.h"

namespace osm_graph_slam {
namespace {

constexpr double kG = 9.80665;

/// A vehicle on a circle of radius 20 m at 8 m/s, heading along its velocity, rising 0.1 m/s:
/// the true pose, world velocity and the ideal IMU (specific force and rate in the body frame).
struct Circle {
  double radius = 20.0, speed = 8.0, climb = 0.1;
  double rate() const { return speed / radius; }
  Eigen::Isometry3d pose(double t) const {
    const double a = rate() * t;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() << radius * std::sin(a), radius * (1.0 - std::cos(a)), climb * t;
    T.linear() = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).matrix();
    return T;
  }
  Eigen::Vector3d velocity(double t) const {
    const double a = rate() * t;
    return {speed * std::cos(a), speed * std::sin(a), climb};
  }
  Eigen::Vector3d accel(double t) const {  // body frame: centripetal plus gravity's reaction
    const Eigen::Vector3d world(-speed * rate() * std::sin(rate() * t),
                                speed * rate() * std::cos(rate() * t), kG);
    return pose(t).linear().transpose() * world;
  }
  Eigen::Vector3d gyro() const { return {0.0, 0.0, rate()}; }
};

TEST(ErrorStateKalmanFilter, PropagationFollowsAKnownTrajectory) {
  const Circle c;
  ErrorStateKalmanFilter f{EskfParams()};
  f.initialize(0.0, c.pose(0.0), c.velocity(0.0), 0.01, 0.001);
  for (int k = 0; k <= 1000; ++k) {  // 10 s at 100 Hz
    const double t = 0.01 * k;
    f.propagate(t, c.accel(t), c.gyro());
  }
  const Eigen::Isometry3d truth = c.pose(10.0);
  std::cout << "[eskf] 10 s of an exact IMU: "
            << (f.state().pose().translation() - truth.translation()).norm() << " m\n";
  // Zero-order hold of an exact IMU over 80 m of a 20 m circle.
  EXPECT_LT((f.state().pose().translation() - truth.translation()).norm(), 0.3);  // 0.20 m
  EXPECT_LT(Eigen::AngleAxisd(truth.linear().transpose() * f.state().pose().linear()).angle(),
            1e-3);
  // The position uncertainty grows without corrections.
  EXPECT_GT(f.covariance()(0, 0), 1e-4);
}

TEST(ErrorStateKalmanFilter, PoseCorrectionsEstimateTheImuBiases) {
  const Circle c;
  const Eigen::Vector3d gyro_bias(0.002, -0.003, 0.01), accel_bias(0.05, -0.08, 0.1);
  EskfParams params;
  ErrorStateKalmanFilter f(params);
  f.initialize(0.0, c.pose(0.0), c.velocity(0.0), 0.05, 0.01);
  std::mt19937 rng(3);
  std::normal_distribution<double> position_noise(0.0, 0.03), angle_noise(0.0, 0.002);
  ErrorStateKalmanFilter::Matrix6d V = ErrorStateKalmanFilter::Matrix6d::Zero();
  V.diagonal() << 0.03 * 0.03, 0.03 * 0.03, 0.03 * 0.03, 4e-6, 4e-6, 4e-6;
  std::vector<double> statistics;
  double worst_late = 0.0;
  for (int k = 1; k <= 6000; ++k) {  // 60 s at 100 Hz, a 10 Hz pose (a LiDAR tracker's)
    const double t = 0.01 * k;
    f.propagate(t, c.accel(t) + accel_bias, c.gyro() + gyro_bias);
    if (k % 10 != 0) continue;
    Eigen::Isometry3d measured = c.pose(t);
    measured.translation() +=
        Eigen::Vector3d(position_noise(rng), position_noise(rng), position_noise(rng));
    measured.linear() = measured.linear() *
                        Eigen::AngleAxisd(angle_noise(rng), Eigen::Vector3d::UnitX()).matrix() *
                        Eigen::AngleAxisd(angle_noise(rng), Eigen::Vector3d::UnitY()).matrix() *
                        Eigen::AngleAxisd(angle_noise(rng), Eigen::Vector3d::UnitZ()).matrix();
    // The prediction 0.1 s ahead of the last correction: what seeds a tracker.
    if (t > 30.0)
      worst_late = std::max(worst_late, (f.state().position - c.pose(t).translation()).norm());
    statistics.push_back(f.correctPose(measured, V));
  }
  std::cout << "[eskf] gyro bias error " << (f.state().gyro_bias - gyro_bias).norm()
            << " rad/s, accel bias error " << (f.state().accel_bias - accel_bias).norm()
            << " m/s^2, worst 0.1 s prediction " << worst_late << " m\n";
  // Measured: 2 % and 5 % of the biases, 0.034 m.
  EXPECT_LT((f.state().gyro_bias - gyro_bias).norm(), 0.05 * gyro_bias.norm());
  EXPECT_LT((f.state().accel_bias - accel_bias).norm(), 0.15 * accel_bias.norm());
  EXPECT_LT(worst_late, 0.06);  // the IMU's prediction over 0.1 s, biases learnt
  // Consistent: the innovations' mean Mahalanobis statistic is near its 6 degrees of freedom.
  double mean = 0.0;
  for (size_t i = statistics.size() / 2; i < statistics.size(); ++i) mean += statistics[i];
  mean /= static_cast<double>(statistics.size() - statistics.size() / 2);
  std::cout << "[eskf] mean innovation statistic " << mean << " (6 expected)\n";
  EXPECT_GT(mean, 4.5);  // measured 5.9
  EXPECT_LT(mean, 7.5);
  // Joseph form: symmetric, positive definite.
  const ErrorStateKalmanFilter::Covariance& P = f.covariance();
  EXPECT_LT((P - P.transpose()).norm(), 1e-12);
  EXPECT_GT(
      Eigen::SelfAdjointEigenSolver<ErrorStateKalmanFilter::Covariance>(P).eigenvalues().minCoeff(),
      0.0);
}

TEST(ErrorStateKalmanFilter, AWrongPoseStandsOutInTheStatistic) {
  const Circle c;
  ErrorStateKalmanFilter f{EskfParams()};
  f.initialize(0.0, c.pose(0.0), c.velocity(0.0), 0.05, 0.01);
  ErrorStateKalmanFilter::Matrix6d V = ErrorStateKalmanFilter::Matrix6d::Identity() * 1e-3;
  for (int k = 1; k <= 200; ++k) {
    const double t = 0.01 * k;
    f.propagate(t, c.accel(t), c.gyro());
    if (k % 10 == 0) EXPECT_LT(f.correctPose(c.pose(t), V), 16.8) << t;
  }
  Eigen::Isometry3d wrong = c.pose(2.0);
  wrong.translation().x() += 2.0;  // an aliased registration 2 m off
  ErrorStateKalmanFilter copy = f;
  EXPECT_GT(copy.correctPose(wrong, V), 100.0);
  EXPECT_LT(f.predictPose(2.05).translation().x() - c.pose(2.05).translation().x(), 0.05);
}

}  // namespace
}  // namespace osm_graph_slam
