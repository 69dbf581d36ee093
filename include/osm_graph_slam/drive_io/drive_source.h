#pragma once
// The drives the offline runners read (offline_slam, offline_localization): a KITTI raw folder
// (real or simulate_urban's), a bag as kitti2bag writes it, or a folder of scans with one
// georeference. Each gives the scans in order with what the GPS/INS said at their time, and a
// prefetcher reads them on their own thread a few ahead of the processing.
#include <Eigen/Geometry>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/slam/sensor_inputs_params.h"

namespace osm_graph_slam {

/// One scan with what the GPS/INS said at its time.
struct DriveScan {
  double stamp = 0.0;
  PointCloudPtr cloud;  ///< null: unreadable (error says why), the scan is skipped
  std::string error;
  std::optional<Eigen::Vector2d> roll_pitch;        ///< base_link in ENU
  std::optional<Eigen::Quaterniond> orientation;    ///< base_link in ENU (INS / IMU), if any
  std::optional<Eigen::Vector3d> angular_velocity;  ///< base_link body rates [rad/s] (gyro), if any
  /// base_link specific force [m/s²] (accelerometer, gravity included), if any
  std::optional<Eigen::Vector3d> linear_acceleration;
  std::optional<Eigen::Isometry3d> truth;  ///< base_link in ENU at the first fix
  std::optional<Eigen::Vector2d> gnss;     ///< the GNSS fix in the same frame
  std::optional<double> gnss_std;  ///< [m] its horizontal deviation, when the receiver reports it
  std::optional<double> gnss_altitude;  ///< [m] the fix's up in the same frame
  /// Set by a ScanPrefetcher's prepare step (offline_slam: the prefilter, run on the reading
  /// thread so that it overlaps the tracking of the scans before); prepare_ms is its time.
  std::optional<CloudPrefilterResult> filtered;
  double prepare_ms = 0.0;
};

/// A drive: origin, initial heading, sensor mounting and the scans in order.
class DriveSource {
 public:
  virtual ~DriveSource() = default;
  virtual size_t size() const = 0;
  /// The next scan; false at the end.
  virtual bool next(DriveScan& scan) = 0;

  double lat = 0, lon = 0, alt = 0;
  std::optional<double> initial_yaw;  ///< ENU yaw of base_link at the first scan
  Eigen::Isometry3d sensor_to_base = Eigen::Isometry3d::Identity();
};

/// Opens the drive named by the command-line arguments (without the leading "--"):
/// kitti-raw [calib-dir] | bag [cloud-topic gps-topic imu-topic ground-truth-topic base-frame]
/// | scans (origin-oxts | origin) [rate calib]. Exactly one of kitti-raw, bag and scans must be
/// given. Null with the reason in error when the drive cannot be opened. program names the caller
/// in notes printed on stderr.
std::unique_ptr<DriveSource> openDriveSource(const std::map<std::string, std::string>& args,
                                             const std::string& program, std::string* error,
                                             const SensorInputsParams& inputs = {});

/// Reads the scans on its own thread, a few ahead of the caller. On a cold disk reading a
/// 2 MB HDL-64E scan takes about as long as processing it (35 vs 40 ms); this way they overlap.
class ScanPrefetcher {
 public:
  /// prepare (optional) runs on the prefetch thread on every readable scan before it is queued.
  using Prepare = std::function<void(DriveScan&)>;
  ScanPrefetcher(DriveSource& source, size_t max_scans, size_t depth, Prepare prepare = {});
  ~ScanPrefetcher();
  /// The next scan in order; false at the end of the drive (or after max_scans).
  bool next(DriveScan& scan);

 private:
  void run();

  DriveSource& source_;
  const size_t max_scans_, depth_;
  const Prepare prepare_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<DriveScan> queue_;
  bool done_ = false, stop_ = false;
  std::thread thread_;  ///< last: starts once everything above exists
};

/// A 40-column progress bar on stderr, redrawn every 10 scans.
void printProgress(size_t done, size_t total);

}  // namespace osm_graph_slam
