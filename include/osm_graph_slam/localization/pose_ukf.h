#pragma once
// Unscented Kalman filter of a vehicle pose for localisation on a map (ART-SLAM LOC, thesis §3.2):
// state = position and orientation of base_link in the map, body-frame velocity, body angular
// rate, gyro bias and accelerometer bias. The orientation lives on SO(3): sigma points perturb it
// by a rotation vector on the right (q ⊞ δ = q · exp(δ)), means of orientations are iterated on
// the manifold.
//
// Prediction: with a gyro reading the orientation turns by (ω_gyro − b_g)·dt; without one by the
// state's own angular rate (constant velocity and turn rate). With an accelerometer reading (the
// specific force f, gravity included, as an IMU gives it) the velocity changes by
// (R·(f − b_a) + g)·dt in the map frame; without one the body velocity is constant and the
// position moves by it rotated at the mid-interval orientation. Correction: a 6-DoF pose
// (scan-to-map registration).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <vector>

namespace osm_graph_slam {

struct PoseUkfParams {
  // Process noise (continuous-time standard deviations, per sqrt(second)).
  double position_noise = 0.05;     ///< [m/√s]
  double velocity_noise = 1.5;      ///< [m/s/√s] the car's unmodelled accelerations
  double orientation_noise = 0.01;  ///< [rad/√s] unmodelled rotation (on top of the gyro)
  double angular_rate_noise = 0.3;  ///< [rad/s/√s] turn-rate changes (constant-rate model)
  double gyro_bias_noise = 1e-4;    ///< [rad/s/√s]
  double gyro_noise = 0.01;         ///< [rad/s] white noise of one gyro reading
  // Accelerometer (used when a reading is given and use_accelerometer is set).
  bool use_accelerometer = true;
  double accel_noise = 0.1;  ///< [m/s²] white noise of one reading
  /// [m/s/√s] what one reading per interval misses of the car's accelerations (replaces
  /// velocity_noise when an accelerometer reading is used)
  double accel_velocity_noise = 0.3;
  double accel_bias_noise = 0.001;  ///< [m/s²/√s]
  double accel_bias_std = 0.1;      ///< [m/s²] initial uncertainty of the bias
  double gravity = 9.81;            ///< [m/s²]
  // Unscented transform: alpha = 1, beta = 2, kappa = 0 (no negative weights on SO(3)).
  double alpha = 1.0;
  double beta = 2.0;
  double kappa = 0.0;
};

/// Error-state layout (18): position, rotation vector, body velocity, body rate, gyro bias,
/// accelerometer bias.
struct PoseUkfState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      ///< body frame [m/s]
  Eigen::Vector3d angular_rate = Eigen::Vector3d::Zero();  ///< body frame [rad/s]
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();     ///< [rad/s]
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();    ///< [m/s²]
};

class PoseUkf {
 public:
  static constexpr int kDim = 18;
  using Covariance = Eigen::Matrix<double, kDim, kDim>;

  explicit PoseUkf(const PoseUkfParams& params = {});

  /// (Re-)starts the filter at pose with the given standard deviations; velocity and rates are
  /// unknown (velocity_std, rate_std) unless given.
  void initialize(const Eigen::Isometry3d& pose, double position_std, double orientation_std,
                  double velocity_std, double rate_std,
                  const Eigen::Vector3d& velocity = Eigen::Vector3d::Zero());

  /// Moves the state dt seconds ahead; gyro: body angular rate measured over the interval;
  /// accel: specific force in the body frame over the interval (gravity included: ~+g up at rest).
  void predict(double dt, const std::optional<Eigen::Vector3d>& gyro = std::nullopt,
               const std::optional<Eigen::Vector3d>& accel = std::nullopt);

  /// Corrects with a measured pose (position std [m], orientation std [rad] per axis). Returns the
  /// squared Mahalanobis distance of the innovation (for gating by the caller, before or after).
  double correct(const Eigen::Isometry3d& measured, double position_std, double orientation_std);

  /// Squared Mahalanobis distance a pose measurement would have, without correcting.
  double mahalanobis(const Eigen::Isometry3d& measured, double position_std,
                     double orientation_std) const;

  bool initialized() const { return initialized_; }
  const PoseUkfState& state() const { return state_; }
  const Covariance& covariance() const { return cov_; }
  Eigen::Isometry3d pose() const;
  /// Position and orientation block (6x6) of the covariance.
  Eigen::Matrix<double, 6, 6> poseCovariance() const { return cov_.topLeftCorner<6, 6>(); }

 private:
  using Vector = Eigen::Matrix<double, kDim, 1>;
  std::vector<PoseUkfState> sigmaPoints(const PoseUkfState& mean, const Covariance& cov) const;
  PoseUkfState boxPlus(const PoseUkfState& x, const Vector& d) const;
  Vector boxMinus(const PoseUkfState& a, const PoseUkfState& b) const;
  PoseUkfState weightedMean(const std::vector<PoseUkfState>& points) const;
  /// Innovation statistics of a pose measurement: mean sigma pose, S and cross covariance.
  void poseInnovation(const Eigen::Isometry3d& measured, double position_std,
                      double orientation_std, Eigen::Matrix<double, 6, 1>& innovation,
                      Eigen::Matrix<double, 6, 6>& S, Eigen::Matrix<double, kDim, 6>& C) const;

  PoseUkfParams params_;
  double lambda_ = 0.0;
  double wm0_ = 0.0, wc0_ = 0.0, wi_ = 0.0;
  bool initialized_ = false;
  PoseUkfState state_;
  Covariance cov_ = Covariance::Identity();
};

/// exp: rotation vector -> quaternion; log: quaternion -> rotation vector (angle in [0, pi]).
Eigen::Quaterniond so3Exp(const Eigen::Vector3d& v);
Eigen::Vector3d so3Log(const Eigen::Quaterniond& q);

}  // namespace osm_graph_slam
