// PrefilteringNodelet: velodyne_points (any frame) -> CloudPrefilter -> filtered_points
// (base_link). The sensor -> base_link transform comes from TF (static) or from parameters.
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <pluginlib/class_list_macros.hpp>

#include <map>
#include <memory>
#include <vector>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/cloud/params_io.h"
#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {

class PrefilteringNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    readParams(RosParamReader(pnh), params_);       // defaults: CloudPrefilterParams
    readParams(RosParamReader(pnh), node_params_);  // defaults: nodelet_params.h
    if (node_params_.reuse_freed_memory && !reuseFreedMemory())
      NODELET_WARN(
          "prefiltering: could not tune the allocator (not glibc?): reuse_freed_memory "
          "has no effect");
    std::vector<double> xyzrpy;
    pnh.param("sensor_to_base", xyzrpy, std::vector<double>(6, 0.0));
    if (xyzrpy.size() != 6) {
      NODELET_ERROR("sensor_to_base must be [x, y, z, roll, pitch, yaw]; using identity");
      xyzrpy.assign(6, 0.0);
    }
    param_sensor_to_base_ =
        fromXyzRpy(xyzrpy[0], xyzrpy[1], xyzrpy[2], xyzrpy[3], xyzrpy[4], xyzrpy[5]);
    if (node_params_.sensor_to_base_from_tf) {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh);
    }
    pub_ = nh.advertise<sensor_msgs::PointCloud2>("filtered_points", 5);
    sub_ = nh.subscribe("velodyne_points", 5, &PrefilteringNodelet::onCloud, this);
    NODELET_INFO("prefiltering: voxel %.2f m (%s), range [%.1f, %.1f] m, outliers %s%s -> %s",
                 params_.voxel_leaf_size, params_.use_voxel_grid ? "on" : "off", params_.min_range,
                 params_.max_range,
                 params_.use_outlier_removal ? params_.outlier_method.c_str() : "off",
                 params_.parallel_octants ? " (8 octants in parallel)" : "",
                 node_params_.base_link_frame.c_str());
  }

  /// sensor -> base_link for a frame: identity for base_link itself, else TF (cached: static)
  /// or the sensor_to_base parameter.
  bool sensorToBase(const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d* out) {
    if (frame == node_params_.base_link_frame || frame.empty()) {
      *out = Eigen::Isometry3d::Identity();
      return true;
    }
    if (!node_params_.sensor_to_base_from_tf) {
      *out = param_sensor_to_base_;
      return true;
    }
    const auto cached = tf_cache_.find(frame);
    if (cached != tf_cache_.end()) {
      *out = cached->second;
      return true;
    }
    try {
      const auto t = tf_buffer_->lookupTransform(node_params_.base_link_frame, frame, ros::Time(0),
                                                 ros::Duration(node_params_.tf_timeout));
      *out = fromTransformMsg(t.transform);
      tf_cache_[frame] = *out;
      return true;
    } catch (const std::exception& e) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "no transform %s -> %s yet (%s); dropping scans", frame.c_str(),
                            node_params_.base_link_frame.c_str(), e.what());
      return false;
    }
  }

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    PointCloud cloud;
    std::string error;
    if (!fromPointCloud2(*msg, cloud, &error)) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period, "dropping scan: %s", error.c_str());
      return;
    }
    Eigen::Isometry3d sensor_to_base;
    if (!sensorToBase(msg->header.frame_id, msg->header.stamp, &sensor_to_base)) return;
    CloudPrefilter prefilter(params_);
    prefilter.setSensorToBase(sensor_to_base);
    const CloudPrefilterResult result = prefilter.filter(cloud);
    if (!result.ok) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period, "scan at %.3f publishes nothing: %s",
                            msg->header.stamp.toSec(), result.reason.c_str());
      return;
    }
    NODELET_DEBUG("prefiltered %zu -> %zu points in %.1f ms", result.stats.input_points,
                  result.stats.output_points, result.stats.time_total_ms);
    boost::shared_ptr<sensor_msgs::PointCloud2> out(new sensor_msgs::PointCloud2);
    toPointCloud2(*result.cloud, *out);
    out->header.stamp = msg->header.stamp;
    out->header.frame_id = node_params_.base_link_frame;
    pub_.publish(boost::shared_ptr<const sensor_msgs::PointCloud2>(out));
  }

  CloudPrefilterParams params_;
  PrefilteringNodeletParams node_params_;  ///< frames, rates, TF (nodelet_params.h)
  Eigen::Isometry3d param_sensor_to_base_ = Eigen::Isometry3d::Identity();
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::map<std::string, Eigen::Isometry3d> tf_cache_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::PrefilteringNodelet, nodelet::Nodelet)
