#pragma once
// Shared by the radar rostest nodes (radar_odometry_node.cpp, radar_slam_node.cpp): simulated
// sweeps as radar/polar images (mono8, frame radar_polar, as mulran2bag writes them), published
// in lock-step with the nodelet's radar/status, and the odometry and status they get back; GNSS
// fixes (gps/fix) and yaw rates (imu/data) as mulran2bag writes them.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "osm_graph_slam/radar/radar_scan.h"

namespace osm_graph_slam::radar_rostest {

inline bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.005).sleep();
  }
  return done();
}

/// The value of key in the first status entry ("" when absent).
inline std::string value(const diagnostic_msgs::DiagnosticArray& a, const std::string& key) {
  if (a.status.empty()) return "";
  for (const auto& kv : a.status[0].values)
    if (kv.key == key) return kv.value;
  return "";
}

inline sensor_msgs::Image toImage(const radar::RadarPolarScan& s, const ros::Time& stamp) {
  sensor_msgs::Image img;
  img.header.stamp = stamp;
  img.header.frame_id = "radar_polar";
  img.height = uint32_t(s.num_azimuths);
  img.width = uint32_t(s.num_bins);
  img.encoding = "mono8";
  img.step = img.width;
  img.data = s.power;
  return img;
}

/// A fix with a known diagonal covariance (sigma per horizontal axis), as mulran2bag writes
/// gps.csv.
inline sensor_msgs::NavSatFix toNavSatFix(double lat, double lon, double alt, double sigma,
                                          const ros::Time& stamp) {
  sensor_msgs::NavSatFix fix;
  fix.header.stamp = stamp;
  fix.header.frame_id = "gps";
  fix.status.status = sensor_msgs::NavSatStatus::STATUS_FIX;
  fix.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS;
  fix.latitude = lat;
  fix.longitude = lon;
  fix.altitude = alt;
  fix.position_covariance = {sigma * sigma, 0, 0, 0, sigma * sigma, 0, 0, 0, 4 * sigma * sigma};
  fix.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_DIAGONAL_KNOWN;
  return fix;
}

/// An Imu with the body rates (x, y, z) [rad/s]; without rates: angular_velocity_covariance[0]
/// = -1 (REP-145), as mulran2bag writes a row of xsens_imu.csv without them.
inline sensor_msgs::Imu toImu(const Eigen::Vector3d& rate, const ros::Time& stamp,
                              bool has_rates = true) {
  sensor_msgs::Imu imu;
  imu.header.stamp = stamp;
  imu.header.frame_id = "imu";
  imu.orientation.w = 1.0;
  imu.orientation_covariance[0] = -1.0;
  imu.angular_velocity.x = rate.x();
  imu.angular_velocity.y = rate.y();
  imu.angular_velocity.z = rate.z();
  if (!has_rates) imu.angular_velocity_covariance[0] = -1.0;
  imu.linear_acceleration_covariance[0] = -1.0;
  return imu;
}

/// Rx holds at least: std::mutex mutex; std::vector<nav_msgs::Odometry> odom;
/// std::vector<diagnostic_msgs::DiagnosticArray> status.
template <class Rx>
class RadarImageFixture : public ::testing::Test {
 protected:
  /// TF listener (before anything is published: /tf is not latched), radar/polar, radar/odom,
  /// radar/status.
  void setUpStream(double tf_cache_s, uint32_t image_queue, uint32_t queue) {
    tf_buffer_ = std::make_unique<tf2_ros::Buffer>(ros::Duration(tf_cache_s));
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
    image_pub_ = nh_.advertise<sensor_msgs::Image>("radar/polar", image_queue);
    odom_sub_ = nh_.subscribe<nav_msgs::Odometry>("radar/odom", queue,
                                                  [this](const nav_msgs::OdometryConstPtr& m) {
                                                    std::lock_guard<std::mutex> lock(rx_.mutex);
                                                    rx_.odom.push_back(*m);
                                                  });
    status_sub_ = nh_.subscribe<diagnostic_msgs::DiagnosticArray>(
        "radar/status", queue, [this](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
          std::lock_guard<std::mutex> lock(rx_.mutex);
          rx_.status.push_back(*m);
        });
  }

  /// gps/fix and imu/data (the topics of mulran2bag and radar.launch).
  void setUpNavigation(uint32_t queue) {
    gps_pub_ = nh_.advertise<sensor_msgs::NavSatFix>("gps/fix", queue);
    imu_pub_ = nh_.advertise<sensor_msgs::Imu>("imu/data", queue);
  }

  /// The nodelet's radar/status reaches this node: a status published before the connection is
  /// up is lost, and send() would wait for it in vain (seen once in CI, on the first sweep).
  bool statusConnected(double timeout_s = 30.0) {
    return waitFor([&] { return status_sub_.getNumPublishers() > 0; }, timeout_s);
  }

  size_t statusCount() {
    std::lock_guard<std::mutex> lock(rx_.mutex);
    return rx_.status.size();
  }

  /// Publishes one image and waits for its status (meanwhile: runs while the nodelet works);
  /// returns that status.
  diagnostic_msgs::DiagnosticArray send(const sensor_msgs::Image& img,
                                        const std::function<void()>& meanwhile = {}) {
    const size_t before = statusCount();
    image_pub_.publish(img);
    if (meanwhile) meanwhile();
    EXPECT_TRUE(waitFor([&] { return statusCount() > before; }, 60.0))
        << "no radar/status for the image at " << img.header.stamp.toSec();
    std::lock_guard<std::mutex> lock(rx_.mutex);
    return rx_.status.empty() ? diagnostic_msgs::DiagnosticArray() : rx_.status.back();
  }

  ros::NodeHandle nh_;
  ros::Publisher image_pub_, gps_pub_, imu_pub_;
  ros::Subscriber odom_sub_, status_sub_;
  Rx rx_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
};

}  // namespace osm_graph_slam::radar_rostest
