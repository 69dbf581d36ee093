#pragma once
// Spinning multi-beam LiDAR model (Velodyne HDL-64E and Ouster OS1-64 presets) ray-cast into a
// World. Deterministic: every ray's noise and dropout come from a hash of (seed, scan, ray), so
// TBB's scheduling cannot change the output.
#include <Eigen/Geometry>
#include <functional>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/sim/surface_texture.h"
#include "osm_graph_slam/sim/world.h"

namespace osm_graph_slam::sim {

struct LidarModel {
  std::string name = "hdl64e";
  std::vector<double> elevations_deg;  ///< one per beam, top to bottom
  int columns = 2083;                  ///< azimuth steps per revolution
  double rate_hz = 10.0;
  double min_range = 2.0;           ///< returns closer than this are dropped (the car body) [m]
  double max_range = 120.0;         ///< [m]
  double range_noise_sigma = 0.02;  ///< [m]
  double dropout_probability = 0.02;
  double intensity_noise_sigma = 0.02;
  /// The intensity's reflectance by surface class and position (sim/surface_texture.h); the
  /// detection of returns keeps the surface's own reflectivity.
  SurfaceTextureParams texture;
  /// Weak returns are lost: a return needs reflectivity * cos(incidence) * (20 m / range)^2 above
  /// this (grazing far ground, dark far surfaces), which brings an HDL-64E to ~120k points.
  double detection_threshold = 0.005;
  double mount_height = 1.73;  ///< above the ground [m] (sets calib / trajectory)
  /// Intrinsic calibration errors: rays leave at elevation + bias + a fixed per-beam error, and
  /// measure range + a fixed per-beam offset, but points are computed from the nominal angles
  /// (what a driver with the factory calibration does). Real HDL-64E calibrations are off by
  /// about this much; KITTI's is known for a ~0.22 deg elevation bias (Deschaud, IMLS-SLAM 2018)
  /// that makes scan matching drift. All zero: a perfect sensor.
  double elevation_bias_deg = 0.0;
  double beam_elevation_sigma_deg = 0.0;
  double beam_range_offset_sigma = 0.0;  ///< [m]

  /// Velodyne HDL-64E: 64 beams, +2.0 deg ... -24.8 deg (upper block 1/3 deg, lower 1/2 deg
  /// spacing), 0.1728 deg azimuth step (2083 columns at 10 Hz).
  static LidarModel hdl64e();
  /// Ouster OS1-64 (MulRan): 64 beams uniformly over +/-16.6 deg, 1024 columns, sigma 3 cm.
  static LidarModel os1_64();
  size_t numRays() const { return elevations_deg.size() * size_t(columns); }
};

struct SimulatedScan {
  PointCloud cloud;              ///< sensor frame at the scan stamp; intensity in [0, 1]
  std::vector<SimLabel> labels;  ///< per point
  std::vector<int32_t> objects;  ///< per point: building index / primitive index / -1
};

/// Sensor pose (world <- sensor) at absolute time t.
using SensorPoseFn = std::function<Eigen::Isometry3d(double t)>;

/// Simulates one revolution stamped at `stamp`. Column c fires at stamp + (c / columns - 0.5) /
/// rate_hz, starting behind the sensor and turning clockwise (like a Velodyne); with
/// motion_distortion the sensor pose of each column's firing time is used, otherwise the pose at
/// the stamp for all columns. Each point is in the sensor frame of its column's firing time, as a
/// driver without motion compensation gives it (KITTI raw); with compensated_sweep it is moved to
/// the sensor frame at the stamp by the true motion (a perfectly deskewed scan).
SimulatedScan simulateScan(const World& world, const LidarModel& model, const SensorPoseFn& pose,
                           double stamp, uint64_t seed, uint64_t scan_index,
                           bool motion_distortion = false, bool compensated_sweep = false);

}  // namespace osm_graph_slam::sim
