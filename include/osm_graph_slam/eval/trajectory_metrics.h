#pragma once
// Trajectory accuracy metrics. ATE and RPE follow the OSM-priors thesis §4.1.2-4.1.3 exactly
// (mean ± std of the translational / rotational part of T_delta), plus RMSE/median/max and the
// KITTI odometry relative errors over 100..800 m segments.
#include <utility>
#include <vector>

#include "osm_graph_slam/io/trajectory_io.h"

namespace osm_graph_slam {

struct ErrorStats {
  size_t count = 0;
  double mean = 0.0, std = 0.0, rmse = 0.0, median = 0.0, max = 0.0;
};
ErrorStats computeErrorStats(std::vector<double> values);

enum class TrajectoryAlignment {
  kNone,       ///< both trajectories already in the same map frame (the thesis' setting)
  kFirstPose,  ///< estimate moved so its first pose equals the ground truth's
  kUmeyamaSE3  ///< least-squares rigid alignment of the positions (Umeyama, no scale)
};

struct TrajectoryEvalOptions {
  double max_time_difference = 0.02;  ///< [s] to associate estimate and ground-truth poses
  TrajectoryAlignment alignment = TrajectoryAlignment::kNone;
  bool planar = false;  ///< evaluate (x, y, yaw) only, as the thesis does in SE(2)
  std::vector<double> kitti_lengths = {100, 200, 300, 400, 500, 600, 700, 800};  ///< [m]
  int kitti_step = 10;  ///< first-frame step of the KITTI devkit
};

struct TrajectoryErrors {
  size_t associated = 0;  ///< pose pairs used
  ErrorStats ate;         ///< [m]
  ErrorStats rpe_trans;   ///< [m] between consecutive associated poses
  ErrorStats rpe_rot;     ///< [rad]
  /// |Δz − Δz₀| [m]: height error less the first pose's (the origin's GNSS altitude error, which
  /// no LiDAR can see), i.e. the height drift since the start.
  ErrorStats height_drift;
  /// Angle between the estimated and the true up axis [rad]: the roll/pitch error.
  ErrorStats tilt;
  size_t kitti_segments = 0;
  double kitti_trans_percent = 0.0;  ///< mean translational drift [%] (0 when no segment fits)
  double kitti_rot_deg_per_100m = 0.0;
  // Per associated pose, for plots: aligned estimate and ground-truth positions, the ATE term
  // and the distance travelled along the ground truth.
  std::vector<Eigen::Vector3d> estimate_positions, ground_truth_positions;
  std::vector<double> ate_per_pose, distance_along_path;
};

/// Pairs (estimate index, ground-truth index) whose stamps differ by at most max_dt; each
/// ground-truth pose is used at most once, order preserved.
std::vector<std::pair<size_t, size_t>> associateByStamp(const Trajectory& estimate,
                                                        const Trajectory& ground_truth,
                                                        double max_dt);

/// Rigid transform T minimising sum |T * a_i - b_i|^2 (Umeyama without scale).
Eigen::Isometry3d alignUmeyama(const std::vector<Eigen::Vector3d>& a,
                               const std::vector<Eigen::Vector3d>& b);

TrajectoryErrors evaluateTrajectory(const Trajectory& estimate, const Trajectory& ground_truth,
                                    const TrajectoryEvalOptions& options = {});

}  // namespace osm_graph_slam
