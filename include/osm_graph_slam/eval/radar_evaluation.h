#pragma once
// Radar odometry against the Oxford Radar RobotCar ground truth (radar_odometry.csv), pair by
// pair for consecutive scans of a drive folder (<dir>/radar/<stamp>.png, <dir>/radar.timestamps).
#include <string>
#include <vector>

#include "osm_graph_slam/radar/radar_odometry.h"

namespace osm_graph_slam::radar {

struct OxfordPairError {
  int64_t destination_stamp_us = 0, source_stamp_us = 0;  ///< radar timestamps (PNG names)
  double gt_x = 0, gt_y = 0, gt_yaw = 0;                  ///< ground truth (Oxford frame)
  double est_x = 0, est_y = 0, est_yaw = 0;               ///< estimate in the Oxford frame
  double translation_error = 0;                           ///< [m] |t_est - t_gt|
  double rotation_error = 0;                              ///< [rad] |yaw_est - yaw_gt|
  bool estimated = false;                                 ///< RANSAC succeeded
  int features = 0, matches = 0, inliers = 0;
  double ms_features = 0, ms_matching = 0, ms_motion = 0;
};

struct OxfordEvaluation {
  bool ok = false;
  std::string error;
  std::vector<OxfordPairError> pairs;
  double gt_length = 0;      ///< [m] sum of ground-truth translations
  double drift_percent = 0;  ///< end-point error of the chained estimate / gt_length * 100
  double mean_translation_error = 0, max_translation_error = 0;
  double mean_rotation_error_deg = 0, max_rotation_error_deg = 0;
  double mean_pair_drift_percent = 0;  ///< mean of translation_error / |t_gt| * 100
};

/// The Oxford radar frame is x forward, y right, z down (RobotCar convention: yaw positive to the
/// right); the odometry's is x forward, y left: y and yaw change sign (checked against the data,
/// see doc/radar.md).
OxfordEvaluation evaluateOxfordDrive(const std::string& drive_dir, const std::string& odometry_csv,
                                     const RadarOdometryParams& params);

}  // namespace osm_graph_slam::radar
