#pragma once
// Shared by the radar rostest nodes (radar_odometry_node.cpp, radar_slam_node.cpp): simulated
// sweeps as radar/polar images (mono8, frame radar_polar, as mulran2bag writes them), published
// in lock-step with the nodelet's radar/status, and the odometry and status they get back.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
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

  size_t statusCount() {
    std::lock_guard<std::mutex> lock(rx_.mutex);
    return rx_.status.size();
  }

  /// Publishes one image and waits for its status; returns that status.
  diagnostic_msgs::DiagnosticArray send(const sensor_msgs::Image& img) {
    const size_t before = statusCount();
    image_pub_.publish(img);
    EXPECT_TRUE(waitFor([&] { return statusCount() > before; }, 60.0))
        << "no radar/status for the image at " << img.header.stamp.toSec();
    std::lock_guard<std::mutex> lock(rx_.mutex);
    return rx_.status.empty() ? diagnostic_msgs::DiagnosticArray() : rx_.status.back();
  }

  ros::NodeHandle nh_;
  ros::Publisher image_pub_;
  ros::Subscriber odom_sub_, status_sub_;
  Rx rx_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
};

}  // namespace osm_graph_slam::radar_rostest
