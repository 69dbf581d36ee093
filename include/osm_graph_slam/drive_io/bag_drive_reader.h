#pragma once
// Reads a drive from a rosbag as kitti2bag writes it (velodyne_points in velo_link, tf_static
// base_link -> velo_link, imu/data, gps/fix, ground_truth) for the offline runner: the small
// topics are read into memory once, the clouds are streamed one at a time in stamp order.
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/attitude.h"  // rollPitchOf, yawOf

namespace osm_graph_slam {

struct BagDriveTopics {
  std::string cloud = "velodyne_points";  ///< sensor_msgs/PointCloud2
  std::string gps = "gps/fix";            ///< sensor_msgs/NavSatFix; the first valid fix = origin
  std::string imu = "imu/data";           ///< sensor_msgs/Imu with an ENU orientation
  std::string ground_truth = "ground_truth";  ///< nav_msgs/Odometry of base_link (optional)
  std::string tf_static = "tf_static";        ///< tf2_msgs/TFMessage
  std::string base_frame = "base_link";
};

struct BagFix {
  int64_t stamp_ns = 0;
  double lat = 0.0, lon = 0.0, alt = 0.0;
  double std_xy = 0.0;  ///< [m] from the message's covariance (0: unknown)
};

/// One IMU vector (body rate or specific force) in base_link.
struct BagImuReading {
  int64_t stamp_ns = 0;
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
};

/// One cloud of the bag: cloud is null (and error says why) for a malformed message.
struct BagCloud {
  int64_t stamp_ns = 0;
  std::string frame_id;
  PointCloudPtr cloud;
  std::string error;
};

class BagDriveReader {
 public:
  BagDriveReader();
  ~BagDriveReader();

  /// Opens the bag, reads fixes, IMU orientations, ground truth and static transforms, and
  /// counts the clouds. False with a reason when the bag cannot be read or holds no cloud.
  bool open(const std::string& path, const BagDriveTopics& topics, std::string* error);

  size_t numClouds() const;
  size_t numImu() const;
  size_t numGroundTruth() const;
  /// The first fix with status >= STATUS_FIX and finite coordinates.
  std::optional<BagFix> firstFix() const;
  /// Every such fix, in the bag's order (SensorInputs matches them to scans by time).
  const std::vector<BagFix>& fixes() const;
  /// Every IMU orientation as base_link in ENU (the static base_link -> IMU frame rotation
  /// applied), in stamp order.
  std::vector<std::pair<int64_t, Eigen::Quaterniond>> orientations() const;
  /// Every IMU body rate (accelerations = false) or specific force (true) in base_link, in the
  /// bag's order; readings whose covariance says the IMU does not give them are left out.
  std::vector<BagImuReading> imuRates(bool accelerations) const;
  /// Ground-truth pose nearest to stamp (within max_dt).
  std::optional<Eigen::Isometry3d> groundTruthAt(int64_t stamp_ns, double max_dt = 0.05) const;
  /// base_link -> frame from tf_static (chains of static transforms are followed); identity
  /// for base_link itself; nullopt when the frame is not connected to base_link.
  std::optional<Eigen::Isometry3d> baseToFrame(const std::string& frame) const;

  /// The next cloud in stamp order; nullopt at the end of the bag.
  std::optional<BagCloud> nextCloud();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace osm_graph_slam
