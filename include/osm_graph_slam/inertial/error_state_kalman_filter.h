#pragma once
// The backbone filter of D3VIL-SLAM (ART-SLAM thesis §6.1): an error-state Kalman filter after
// Solà ("Quaternion kinematics for the error-state Kalman filter", 2017). The nominal state
// (position, velocity, orientation, accelerometer and gyro biases: 16 numbers) is propagated by
// the IMU; the 15-dimensional error state (orientation as a local angle) carries the covariance.
// Pose measurements (the LiDAR tracker's, the visual tracker's) correct it in Joseph form; the
// estimated error is injected into the nominal state and the error reset.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace osm_graph_slam {

struct EskfParams {
  /// IMU noise densities and bias random walks (continuous time; the discrete noise of a step of
  /// dt is these squared times dt, Solà §5.4.3). Defaults: a consumer MEMS IMU.
  double accel_noise = 0.02;         ///< [m/s^2/sqrt(Hz)]
  double gyro_noise = 0.002;         ///< [rad/s/sqrt(Hz)]
  double accel_bias_walk = 0.001;    ///< [m/s^3/sqrt(Hz)]
  double gyro_bias_walk = 0.0001;    ///< [rad/s^2/sqrt(Hz)]
  double gravity = 9.80665;          ///< [m/s^2] along -z of the world frame
  double init_velocity_std = 1.0;    ///< [m/s]
  double init_accel_bias_std = 0.2;  ///< [m/s^2]
  double init_gyro_bias_std = 0.01;  ///< [rad/s]
  double max_step = 0.05;  ///< [s] a longer gap between IMU samples is integrated in steps
};

/// The nominal state: body (IMU) pose in the world, world velocity, biases in the body frame.
struct EskfState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< world <- body
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Isometry3d pose() const;
};

class ErrorStateKalmanFilter {
 public:
  using Covariance = Eigen::Matrix<double, 15, 15>;  ///< dp, dv, dtheta, dab, dwb
  using Matrix6d = Eigen::Matrix<double, 6, 6>;

  explicit ErrorStateKalmanFilter(const EskfParams& params) : params_(params) {}

  /// Starts at `pose` (world <- body) with the given position/orientation deviations.
  void initialize(double stamp, const Eigen::Isometry3d& pose, const Eigen::Vector3d& velocity,
                  double position_std, double orientation_std);
  bool initialized() const { return initialized_; }

  /// One IMU sample (specific force and angular rate in the body frame) at `stamp`: the state is
  /// propagated from the previous sample's time with the previous sample held (zero-order).
  void propagate(double stamp, const Eigen::Vector3d& accel, const Eigen::Vector3d& gyro);
  /// The pose predicted at `stamp` (after the last sample) without changing the filter.
  Eigen::Isometry3d predictPose(double stamp) const;

  /// A measured pose (world <- body) with its 6x6 covariance (position, then the local rotation
  /// angle). Returns the squared Mahalanobis distance of the innovation (a consistency test for
  /// the caller: 6 degrees of freedom, 99 % at 16.8).
  double correctPose(const Eigen::Isometry3d& measured, const Matrix6d& covariance);

  const EskfState& state() const { return state_; }
  const Covariance& covariance() const { return P_; }
  double stamp() const { return stamp_; }

 private:
  /// One step of dt with the sample held: nominal kinematics and the error covariance.
  void step(double dt, const Eigen::Vector3d& accel, const Eigen::Vector3d& gyro);
  void inject(const Eigen::Matrix<double, 15, 1>& dx);

  EskfParams params_;
  EskfState state_;
  Covariance P_ = Covariance::Zero();
  double stamp_ = 0.0;
  bool initialized_ = false;
  Eigen::Vector3d last_accel_ = Eigen::Vector3d::Zero(), last_gyro_ = Eigen::Vector3d::Zero();
  bool have_sample_ = false;
};

}  // namespace osm_graph_slam
