#pragma once
// The LiDAR's mounting (TF base_link <- sensor frame) for the nodelets that deskew scans already
// moved into base_link: scan matching and localisation. Looked up on each scan, without waiting,
// until found; one warning while it is missing.
#include <ros/ros.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>

namespace osm_graph_slam {

class SensorMountLookup {
 public:
  SensorMountLookup(ros::NodeHandle& nh, std::string base_frame, std::string sensor_frame);
  /// The mounting once TF has it (then cached: it is static); nothing while it is missing.
  std::optional<Eigen::Isometry3d> get();
  const std::string& sensorFrame() const { return sensor_frame_; }

 private:
  // Dropped once the mounting is found: every listener logs each jump back of /clock.
  std::unique_ptr<tf2_ros::Buffer> buffer_;
  std::unique_ptr<tf2_ros::TransformListener> listener_;
  std::string base_frame_, sensor_frame_;
  bool tried_ = false;
  std::optional<Eigen::Isometry3d> found_;
};

}  // namespace osm_graph_slam
