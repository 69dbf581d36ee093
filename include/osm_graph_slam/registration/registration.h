#pragma once
// Interface of every 3D registration back-end (ours and the PCL baselines). Implementations keep
// PCL/TBB templates in their .cpp files; this header stays light.
#include <Eigen/Geometry>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct RegistrationResult {
  /// Maps source points into the target frame (p_target = transform * p_source).
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  bool converged = false;
  /// Mean squared distance of inlier correspondences at the solution [m^2].
  double fitness = std::numeric_limits<double>::infinity();
  /// Gauss-Newton Hessian of the cost at the solution for a perturbation applied on the left in
  /// the target frame, ordered (translation, rotation); zero when the back-end gives none (the
  /// PCL baselines). Its inverse is the match's covariance only up to a scale: GICP counts
  /// neighbouring points as independent evidence (odometry information, doc/backend.md).
  Eigen::Matrix<double, 6, 6> hessian = Eigen::Matrix<double, 6, 6>::Zero();
  int iterations = 0;
  double time_ms = 0.0;
  std::string message;  ///< why it failed, when it did
};

/// Parameters shared by every back-end; each back-end reads the fields it understands.
struct RegistrationParams {
  std::string method = "fast_gicp";  ///< fast_gicp | fast_vgicp (ours) | pcl_gicp | pcl_ndt
  int num_threads = 0;               ///< 0 = all hardware threads
  int max_iterations = 64;
  double max_correspondence_distance = 1.0;  ///< [m]
  double transformation_epsilon = 5e-4;      ///< convergence on the update norm [m, rad]
  int k_correspondences = 10;                ///< neighbours for point covariances (GICP)
  double ndt_resolution = 1.0;               ///< [m] (NDT)
  double ndt_step_size = 0.1;                ///< [m] More-Thuente line search step (NDT)
  /// GICP covariance regularisation: eigenvalues become (epsilon, 1, 1) (plane model).
  double gicp_covariance_epsilon = 1e-3;
  double vgicp_resolution = 1.0;  ///< [m] voxel size of the target distributions (fast_vgicp)
  /// Fewer inlier correspondences than this fails the match (fast_gicp).
  int min_correspondences = 20;
  /// Prepared targets (KD-tree, covariances) kept for setTarget() of the same cloud object again,
  /// least recently used dropped first (fast_gicp / fast_vgicp; ~0.5 MB each at 5k points). Not
  /// read from the parameter files: the loop detector sets it (candidate_cache_size).
  int target_cache_size = 1;
  /// Source points aligned at most (fast_gicp / fast_vgicp; 0: all): evenly spaced in the
  /// source KD-tree's leaf order (so spread evenly in space); every source point still serves as
  /// a neighbour for the covariances, and the overlap is measured as before. Not read from the
  /// parameter files: the loop detector sets it (fine_max_source_points).
  int max_source_points = 0;
};

/// Back-ends may keep the preprocessing (KD-tree, covariances) of the cloud objects they were
/// last given as source and target and reuse it when the same object (pointer) comes again, so
/// a cloud must not be modified after it was passed in.
class Registration {
 public:
  virtual ~Registration() = default;
  virtual std::string name() const = 0;
  /// Sets (and preprocesses, e.g. indexes and computes covariances of) the target cloud.
  virtual void setTarget(const PointCloudConstPtr& target) = 0;
  /// Aligns source to the current target starting from guess. Never throws on bad input:
  /// returns converged = false with a message instead.
  virtual RegistrationResult align(const PointCloudConstPtr& source,
                                   const Eigen::Isometry3d& guess) = 0;
  /// Fraction of source's points (all of them count; non-finite ones never match) that lie within
  /// max_distance of the current target once moved by transform, measured on the index the
  /// back-end already keeps for the target; nullopt when it keeps none (the caller measures).
  virtual std::optional<double> overlap(const PointCloud& source,
                                        const Eigen::Isometry3d& transform,
                                        double max_distance) const {
    (void)source, (void)transform, (void)max_distance;
    return std::nullopt;
  }
};

/// Creates the back-end named by params.method; throws std::invalid_argument for an unknown name.
std::unique_ptr<Registration> createRegistration(const RegistrationParams& params);

}  // namespace osm_graph_slam
