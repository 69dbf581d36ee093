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
};

}  // namespace osm_graph_slam
