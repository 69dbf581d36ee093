#pragma once
// Dataset folder -> rosbag conversions behind the kitti2bag and mulran2bag tools (a library so
// tests run them in-process). Bags are written to "<bag>.tmp" and renamed when complete.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace osm_graph_slam {

/// Called after each processed item (done of total).
using ProgressFn = std::function<void(size_t done, size_t total)>;

struct BagConversionResult {
  bool ok = false;
  std::string error;  ///< the first missing or malformed file, when !ok
  size_t clouds = 0, gps = 0, imu = 0, ground_truth = 0, images = 0, tf_static = 0;
  size_t skipped = 0;                 ///< unreadable inputs left out (scan folders only)
  std::vector<std::string> warnings;  ///< one line per skipped input, and notes
  double first_stamp = 0.0;           ///< [s] stamp of the first message (scan folders)
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

/// KITTI raw: 2011-09-26 00:00:00 UTC, the recording day of the KITTI raw drives of
/// ../shared/data; the first scan of a folder without timestamps is stamped here.
constexpr double kScanFolderDefaultStart = 1316995200.0;

/// A folder of KITTI .bin scans with one georeference for the first scan and no per-scan OXTS
/// (kitti2bag --scans; the bag counterpart of offline_slam --scans).
struct ScanFolderBagOptions {
  std::string scans_dir;    ///< *.bin, in name order; scan i is stamped start + i / rate
  std::string origin_oxts;  ///< a KITTI OXTS record of the first scan (exactly one of these two)
  std::string origin;       ///< "LAT,LON,ALT[,YAW_DEG]"
  /// calib_imu_to_velo.txt or a tracking-layout file with Tr_imu_to_velo; base_link is then the
  /// OXTS unit as in KITTI raw. Empty: base_link = the LiDAR frame (identity tf_static).
  std::string calib_path;
  std::string bag_path;
  double rate = 10.0;  ///< [Hz]
  /// [s] stamp of the first scan; < 0: the OXTS record's line of ../timestamps.txt when the
  /// record sits in a KITTI raw oxts/data/ folder, else kScanFolderDefaultStart.
  double start_time = -1.0;
  std::string cloud_topic = "velodyne_points";
  std::string gps_topic = "gps/fix";
  std::string imu_topic = "imu/data";
  std::string base_frame = "base_link";
  std::string velo_frame = "velo_link";
  std::string imu_frame = "imu_link";
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
/// Writes velodyne_points at start + i / rate, tf_static base_link -> velo_link (from the
/// calibration) and base_link -> imu_link at the first stamp, ONE gps/fix at the first stamp (the
/// map origin) and, when the georeference has an attitude, ONE imu/data there (--origin-oxts: the
/// record's orientation, rates and accelerations; --origin with a yaw: that yaw with roll = pitch
/// = 0, rates and accelerations unknown). Unreadable or empty scans are skipped (their stamp
/// stays free) and listed in warnings; an empty or missing folder, a bad origin or calibration,
/// or no readable scan at all is an error before any bag exists.
BagConversionResult convertScanFolderToBag(const ScanFolderBagOptions& options,
                                           const ProgressFn& progress = {});
BagConversionResult convertMulranToBag(const MulranBagOptions& options,
                                       const ProgressFn& progress = {});

/// A one-line progress bar on stderr ("\r[=====     ]  50% 12/24"), redrawn on each percent.
ProgressFn stderrProgressBar(const std::string& label);

}  // namespace osm_graph_slam
