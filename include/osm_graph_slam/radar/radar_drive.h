#pragma once
// Radar odometry and SLAM (radar_slam.h) over a MulRan-layout drive (the dataset or simulate_urban
// --sensor navtech): every radar/polar PNG listed in data_stamp.csv in order, the ground truth from
// global_pose.csv interpolated at each sweep's mid time, per-stage timings. A PNG that cannot be
// read is reported and skipped; the next sweep is matched against the last good one.
#include <functional>
#include <string>
#include <vector>

#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/radar/radar_slam.h"

namespace osm_graph_slam::radar {

struct RadarDriveOptions {
  MulranPolarLayout layout;
  int max_scans = 0;  ///< 0: all
};

struct RadarDriveResult {
  bool ok = false;
  std::string error;                 ///< why the drive could not be run at all
  std::vector<std::string> skipped;  ///< per unreadable sweep: the reader's message
  Trajectory odometry;               ///< radar pose at each sweep's mid time, first = identity
  Trajectory trajectory;             ///< the same sweeps after the pose graph (loops)
  std::vector<RadarLoop> loops;
  RadarLoopStats loop_stats;
  RadarNavStats nav_stats;  ///< GNSS fixes (gps.csv) and yaw rates (xsens_imu.csv) used
  size_t keyframes = 0;
  Trajectory ground_truth;  ///< global_pose at the same times, in the first pose's frame
  std::vector<RadarOdometryStep> steps;  ///< without feature sets (they are dropped to save memory)
  std::vector<RadarFeatureSet> keyframe_features;  ///< filled by the caller if wanted
  int scans = 0, failed = 0;                       ///< read sweeps; RANSAC failures
  int registered = 0;                              ///< sweeps refined against the local map
  double ms_read = 0, ms_features = 0, ms_matching = 0, ms_motion = 0,
         ms_registration = 0;  ///< per sweep, mean
  double span_s = 0;           ///< first to last sweep [s]
};

/// The 3D pose of a planar one (z = 0, yaw only).
Eigen::Isometry3d planarTo3d(const Eigen::Isometry2d& T);

/// Runs the odometry and the back-end. on_step (may be empty) sees every step with its feature set
/// (keyframes, loop detection) before the features are dropped.
RadarDriveResult runMulranRadarSlam(
    const std::string& root, const RadarSlamParams& params, const RadarDriveOptions& options,
    const std::function<void(const RadarOdometryStep&, const RadarPolarScan&)>& on_step = {});

}  // namespace osm_graph_slam::radar
