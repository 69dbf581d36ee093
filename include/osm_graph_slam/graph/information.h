#pragma once
// Information matrices: odometry-like SE3 edges from a registration fitness; planar edges whose
// measurement pins a point away from the pose (lever arm).
#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam {

/// Odometry edge information from the registration fitness (hdl_graph_slam style): the standard
/// deviations grow linearly from min to max as the fitness grows to max_fitness. Standard
/// deviations are in metres and radians and are squared into variances.
struct InformationParams {
  double min_std_xyz = 0.01, max_std_xyz = 0.23;    ///< [m]
  double min_std_rot = 0.001, max_std_rot = 0.005;  ///< [rad] roll and pitch (doc/backend.md)
  /// [rad] yaw (about the keyframe's z axis) separately: scan matching measures heading far
  /// better than roll/pitch or translation (simulated: 0.03 mrad vs 5 mm per 2 m keyframe), and a
  /// loose yaw let robot<->building edges kink the heading (rotation RPE 1.8-2.9x odometry's).
  double min_std_yaw = 0.0001, max_std_yaw = 0.001;
  double max_fitness = 0.5;  ///< fitness [m^2] at and above which the max deviations apply
  /// Translation deviations across the direction of motion (sideways and vertical) relative to
  /// the deviation along it. Scan matching in streets errs along the street (simulated 1.5 km:
  /// along-track step error std 9 mm, lateral 3 mm), and isotropic deviations let
  /// robot<->building edges jitter keyframes sideways.
  double lateral_std_ratio = 0.3;
  /// Geometry as evidence: this times the match's own information (its GICP Hessian, moved to
  /// the edge's error coordinates) is added to the fitness-based information, so a direction the
  /// scene constrains well (along a square's walls) is held where the fitness model, which only
  /// knows streets, assumes it weak. The Hessian counts neighbouring points as independent, so
  /// the weight is far below 1 (doc/backend.md). 0 = off; keyframes without a Hessian (PCL
  /// registration, old dumps) get the fitness model alone. 0.0025 together with the odometry
  /// scale and prediction_error_scale 1 (see odometry_scale_window).
  double hessian_weight = 0.0025;
  /// A keyframe whose match lay an offset e from the motion model's prediction (TrackResult::
  /// prediction_error: the scan was deskewed by a motion that did not happen) gets
  /// (scale * e)(scale * e)^T added to its translation covariance: along e the step is
  /// uncertain by about that much, whatever fitness and Hessian say. 0 = off (alone: neutral
  /// on the quick matrix, 0.4-1.1 % more ATE on the manoeuvre drives; doc/backend.md). 1 together
  /// with the Hessian and the odometry scale.
  double prediction_error_scale = 1.0;
};

/// 6×6 information (x y z, then rotation; block-diagonal) whose standard deviations grow linearly
/// from the minimum to the maximum as fitness goes from 0 to max_fitness; a negative (unknown)
/// fitness uses the middle of the range. Standard deviations are squared into variances.
/// `motion` is the edge's translation in its frame: across it the translation deviation is
/// lateral_std_ratio times the deviation along it (isotropic for motions under 5 cm).
Matrix6d odometryInformation(double fitness, const InformationParams& params,
                             const Eigen::Vector3d& motion = Eigen::Vector3d::Zero());

/// A registration's Hessian (RegistrationResult::hessian: left perturbation of `relative`, the
/// match's source-to-target transform, in the target frame) as information of an SE3 edge
/// measuring `relative`, in PoseGraph's error coordinates (right perturbation; the rotation
/// error is a quaternion's vector part, half the angle).
Matrix6d registrationInformation(const Matrix6d& hessian, const Eigen::Isometry3d& relative);

/// The translation's information with the rotation unknown (Schur complement of the rotation
/// block): what `info` says about the translation alone.
Eigen::Matrix3d translationMarginal(const Matrix6d& info);

/// `info` with an independent deviation `offset` (its length, along its direction) added to its
/// covariance: (info^-1 + offset offset^T)^-1, also for a singular info.
Eigen::Matrix3d withDeviationAlong(const Eigen::Matrix3d& info, const Eigen::Vector3d& offset);

/// Planar (x, y, theta) information of a pose from a measurement that pins the point `lever`
/// away from it (same frame), given as information at that point: a rotation about the pose
/// moves the point by theta × lever, so position and heading errors are coupled.
Eigen::Matrix3d leverInformation(const Eigen::Matrix3d& info_at_point,
                                 const Eigen::Vector2d& lever);

}  // namespace osm_graph_slam
