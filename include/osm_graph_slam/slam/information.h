#pragma once
// Information matrices: odometry-like SE3 edges from a registration fitness; planar edges whose
// measurement pins a point away from the pose (lever arm).
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/slam/backend_params.h"

namespace osm_graph_slam {

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

/// The line matcher's information (§3.3.5: by feature type, scaled by fitness) rescaled so that
/// the best possible match (edge feature, full fitness) has the given standard deviations.
Eigen::Matrix3d scaledInformation(const Eigen::Matrix3d& matcher_info, double std_xy,
                                  double std_theta, const LineMatcherParams& m);

}  // namespace osm_graph_slam
