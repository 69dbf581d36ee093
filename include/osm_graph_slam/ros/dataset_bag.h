#pragma once
// Dataset folder -> rosbag conversions behind the kitti2bag and mulran2bag tools (a library so
// tests run them in-process). Bags are written to "<bag>.tmp" and renamed when complete.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

namespace osm_graph_slam {

/// Called after each processed item (done of total).
using ProgressFn = std::function<void(size_t done, size_t total)>;

struct BagConversionResult {
  bool ok = false;
  std::string error;  ///< the first missing or malformed file, when !ok
  size_t clouds = 0, gps = 0, imu = 0, ground_truth = 0, images = 0, tf_static = 0;
};

struct KittiRawBagOptions {
  std::string drive_dir;  ///< .../<date>_drive_<n>_sync
  std::string calib_dir;  ///< empty: the drive folder, then its parent
  std::string bag_path;
  std::string cloud_topic = "velodyne_points";
  std::string gps_topic = "gps/fix";
  std::string imu_topic = "imu/data";
  std::string ground_truth_topic = "ground_truth";
  std::string base_frame = "base_link";
  std::string velo_frame = "velo_link";
  std::string imu_frame = "imu_link";
  std::string enu_frame = "enu";  ///< ENU frame anchored at the first fix (ground truth)
};

struct KittiOdometryBagOptions {
  std::string sequence_dir;  ///< .../sequences/NN
  std::string poses_path;    ///< empty: ../../poses/NN.txt when present
  std::string bag_path;
  std::string cloud_topic = "velodyne_points";
  std::string ground_truth_topic = "ground_truth";
  std::string velo_frame = "velo_link";
  std::string world_frame = "world";  ///< the first LiDAR pose
  /// times.txt starts at 0 and bags need stamps > 0: stamp = start_time + times[i].
  double start_time = 1.0;
};

struct MulranBagOptions {
  std::string root;  ///< the folder holding global_pose.csv and sensor_data/
  std::string bag_path;
  std::string cloud_topic = "os1_points";
  std::string gps_topic = "gps/fix";
  std::string imu_topic = "imu/data";
  std::string ground_truth_topic = "ground_truth";
  std::string radar_topic = "radar/polar";
  std::string base_frame = "base_link";
  std::string ouster_frame = "ouster";
  std::string imu_frame = "imu";
  std::string gps_frame = "gps";
  std::string radar_frame = "radar_polar";
  std::string world_frame = "world";
  /// true: global_pose.csv as is (UTM-like numbers); false: relative to the first pose.
  bool absolute_ground_truth = false;
  bool skip_missing = false;  ///< skip scans/images listed in data_stamp.csv but absent
};

BagConversionResult convertKittiRawToBag(const KittiRawBagOptions& options,
                                         const ProgressFn& progress = {});
BagConversionResult convertKittiOdometryToBag(const KittiOdometryBagOptions& options,
                                              const ProgressFn& progress = {});
BagConversionResult convertMulranToBag(const MulranBagOptions& options,
                                       const ProgressFn& progress = {});

/// A one-line progress bar on stderr ("\r[=====     ]  50% 12/24"), redrawn on each percent.
ProgressFn stderrProgressBar(const std::string& label);

}  // namespace osm_graph_slam
