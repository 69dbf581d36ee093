#include "osm_graph_slam/ros/sensor_mount_lookup.h"

#include <utility>

#include "osm_graph_slam/ros/conversions.h"

namespace osm_graph_slam {

SensorMountLookup::SensorMountLookup(ros::NodeHandle& nh, std::string base_frame,
                                     std::string sensor_frame)
    : buffer_(std::make_unique<tf2_ros::Buffer>()),
      listener_(std::make_unique<tf2_ros::TransformListener>(*buffer_, nh)),
      base_frame_(std::move(base_frame)),
      sensor_frame_(std::move(sensor_frame)) {}

std::optional<Eigen::Isometry3d> SensorMountLookup::get() {
  if (found_) return found_;
  const bool first = !tried_;
  tried_ = true;
  try {
    // Never waits: a timeout runs on the ROS clock, and under a simulated clock that a test or
    // rosbag advances only when outputs arrive, a wait in the scan callback stalls the pipeline.
    const auto t = buffer_->lookupTransform(base_frame_, sensor_frame_, ros::Time(0));
    found_ = fromTransformMsg(t.transform);
    listener_.reset();
    buffer_.reset();
    ROS_INFO("deskewing about %s (TF from %s)", sensor_frame_.c_str(), base_frame_.c_str());
  } catch (const tf2::TransformException& e) {
    if (first)
      ROS_WARN("deskewing: no TF %s <- %s yet (%s): azimuths taken about %s until it comes",
               base_frame_.c_str(), sensor_frame_.c_str(), e.what(), base_frame_.c_str());
  }
  return found_;
}

}  // namespace osm_graph_slam
