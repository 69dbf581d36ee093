#pragma once
// Parameters of SensorInputs (graph_backend.yaml), in a header of their own so that the drive
// readers need not include the back-end's.
#include <cstddef>

namespace osm_graph_slam {

/// How IMU and GNSS samples are matched to keyframes by time (SensorInputs), in the nodelet and
/// the offline runners alike.
struct SensorInputsParams {
  bool use_imu = true;                    ///< IMU attitude: initial heading + roll/pitch priors
  double imu_max_time_difference = 0.05;  ///< [s] a keyframe's IMU sample at most this far
  /// [s] first keyframe without an IMU sample that close: the newest one up to this old gives
  /// the heading (a first scan lost at start-up; kitti2bag --scans has one sample at scan 0)
  double initial_heading_max_age = 1.0;
  double gnss_max_gap = 1.5;  ///< [s] the fix is interpolated between fixes this close, ...
  double gnss_max_time_difference = 0.05;  ///< [s] ... else the nearest fix this close
  /// Samples kept per sensor (the oldest go first); 0 keeps all (offline: the whole drive).
  size_t max_samples = 2000;

  /// The keys of config/graph_backend*.yaml (common/param_declaration.h); max_samples is set by
  /// the code that owns the buffers.
  template <class V>
  void visit(V& v) {
    v("use_imu", use_imu,
      "imu/data (REP-145, orientation in ENU): initial heading + roll/pitch priors");
    v("imu_max_time_difference", imu_max_time_difference,
      "[s] IMU sample used for a keyframe at most this far from its stamp");
    v("initial_heading_max_age", initial_heading_max_age,
      "[s] first keyframe without an IMU sample that close: the newest one up to this old gives "
      "the heading");
    v("gnss_max_gap", gnss_max_gap,
      "[s] the first keyframe is fixed at gps/fix interpolated between fixes this close,");
    v("gnss_max_time_difference", gnss_max_time_difference,
      "[s] ... else at the nearest fix this close (else at the map origin, the first fix)");
  }
};

}  // namespace osm_graph_slam
