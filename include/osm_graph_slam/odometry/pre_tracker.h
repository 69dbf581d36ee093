#pragma once
// Pre-tracker (ART-SLAM thesis §3.1.5): the motion since the previous scan, from that scan
// alone, heavily downsampled and registered at two scales (coarse, then finer). Scan-to-scan
// motion is small (one sensor period), so it holds through sharp turns and strong accelerations
// that a constant-velocity guess extrapolated from the previous motion does not. The tracker uses
// it as its initial guess (guess: pre_tracker) or to recover after a failed match.
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/odometry/fitness_gate.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

struct PreTrackerParams {
  // Coarse scales (doc/frontend.md "why 4.0/2.0 m are the defaults"): the pre-tracker only has
  // to bring the tracker into its basin, and its cost is the per-scan preparation of both scales.
  double coarse_voxel = 4.0;               ///< [m] leaf of the coarse scale
  double fine_voxel = 2.0;                 ///< [m] leaf of the finer scale
  double coarse_max_correspondence = 4.0;  ///< [m]
  double fine_max_correspondence = 2.5;    ///< [m]
  double max_fitness = 1.0;                ///< [m^2] a worse fine match gives no estimate
  double fitness_ratio = 4.0;  ///< ... or one worse than this times the recent median (0: off)
  double fitness_ratio_floor = 0.2;  ///< [m^2] (see KeyframeTrackerParams)
  /// Registration back-end of both scales ("": the tracker's). fast_vgicp finds correspondences
  /// by a voxel lookup instead of a KD-tree search (frontend_benchmark measures both).
  std::string method;
  int max_iterations = 0;  ///< per scale (0: the tracker's)
};

struct PreTrackerEstimate {
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  ///< current scan in previous's frame
  double fitness = 0.0;
  double time_ms = 0.0;
};

class PreTracker {
 public:
  PreTracker(const PreTrackerParams& params, const RegistrationParams& registration);
  ~PreTracker();

  /// Keeps the scan; the next estimate() registers against it. Free: the scan is downsampled
  /// only when an estimate is asked for (the tracker asks only to recover, by default).
  void remember(const PointCloudConstPtr& cloud);
  /// Motion of `cloud` relative to the remembered scan, starting from `guess`; nothing when no
  /// scan is remembered or the match fails (fitness above max_fitness or the adaptive gate).
  /// Its fitness is in its own units (NN distances between 2 m voxels are ~10x the tracker's),
  /// so the tracker's gate does not apply here; the tracker verifies the guess by its own match.
  /// Does not remember `cloud`.
  std::optional<PreTrackerEstimate> estimate(const PointCloudConstPtr& cloud,
                                             const Eigen::Isometry3d& guess);
  bool ready() const { return previous_ != nullptr; }
  void reset();

 private:
  PreTrackerParams params_;
  std::unique_ptr<Registration> coarse_, fine_;
  FitnessGate fitness_gate_;
  PointCloudConstPtr previous_;                         ///< the remembered scan
  PointCloudConstPtr previous_coarse_, previous_fine_;  ///< its copies, made on demand
  PointCloudConstPtr current_coarse_, current_fine_;    ///< of the cloud last estimated
  const PointCloud* current_source_ = nullptr;
};

}  // namespace osm_graph_slam
