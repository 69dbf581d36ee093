// OsmLocalizationNodelet: localisation from OpenStreetMap alone (issue 21 item 4,
// doc/localization.md): no prior drive, no point-cloud map. A thin adapter around OsmLocalizer:
//   filtered_points (base_link) + odom (scan_matching: base_link in odom, the same stamps)
//   + gps/fix + imu/data (heading at the start) + osm/origin, osm/buildings (osm_buffer)
//   -> osm_localization/odom (base_link in map), osm_localization/pose (osm_buffer queries
//      around it), osm_localization/status (every scan), TF map -> odom.
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <osm_graph_slam/BuildingArray.h>
#include <osm_graph_slam/OsmLocalizationReport.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/transform_broadcaster.h>
#include <pluginlib/class_list_macros.hpp>

#include <chrono>
#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "osm_graph_slam/localization/osm_localizer.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/osm_conversions.h"
#include "osm_graph_slam/ros/ros_param_reader.h"
#include "osm_graph_slam/ros/wall_matching_params.h"
#include "osm_graph_slam/slam/sensor_inputs.h"

namespace osm_graph_slam {

class OsmLocalizationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    readParams(RosParamReader(pnh), node_params_);  // defaults: nodelet_params.h
    OsmLocalizerParams params;
    readParams(RosParamReader(pnh), params);
    bool found = false;
    const WallMatchingParams w = readWallMatchingParams(node_params_.line_extraction_ns,
                                                        node_params_.line_matcher_ns, &found);
    if (!found)
      NODELET_WARN(
          "osm_localization: no wall extraction / line matcher parameters under %s and "
          "%s (config/line_extraction.yaml, graph_backend.yaml); using built-in defaults",
          node_params_.line_extraction_ns.c_str(), node_params_.line_matcher_ns.c_str());
    localizer_ = std::make_unique<OsmLocalizer>(params, std::vector<Building>{}, w.walls,
                                                w.segments, w.matcher);

    odom_pub_ = nh.advertise<nav_msgs::Odometry>("osm_localization/odom", 10);
    pose_pub_ = nh.advertise<geometry_msgs::PoseStamped>("osm_localization/pose", 10);
    status_pub_ = nh.advertise<OsmLocalizationReport>("osm_localization/status", 10);
    cloud_sub_ = nh.subscribe("filtered_points", 10, &OsmLocalizationNodelet::onCloud, this);
    odom_sub_ = nh.subscribe("odom", 50, &OsmLocalizationNodelet::onOdom, this);
    fix_sub_ = nh.subscribe("gps/fix", 50, &OsmLocalizationNodelet::onFix, this);
    if (node_params_.use_imu)
      imu_sub_ = nh.subscribe("imu/data", 200, &OsmLocalizationNodelet::onImu, this);
    origin_sub_ = nh.subscribe("osm/origin", 1, &OsmLocalizationNodelet::onOrigin, this);
    buildings_sub_ = nh.subscribe("osm/buildings", 10, &OsmLocalizationNodelet::onBuildings, this);
    NODELET_INFO(
        "osm_localization: walls every %.1f m within %.0f m, datum %.1f m, GNSS %s, IMU heading "
        "%s; waiting for osm/origin and osm/buildings",
        params.match_every_distance, params.query_radius, params.datum_std,
        params.use_gnss ? "on" : "off", node_params_.use_imu ? "on" : "off");
  }

  // --- inputs ----------------------------------------------------------------------------------
  void onOrigin(const sensor_msgs::NavSatFixConstPtr& fix) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (origin_ || !std::isfinite(fix->latitude) || !std::isfinite(fix->longitude)) return;
    const double alt = std::isfinite(fix->altitude) ? fix->altitude : 0.0;
    origin_.emplace(fix->latitude, fix->longitude, alt);
    inputs_.setOrigin(fix->latitude, fix->longitude, fix->altitude);
    NODELET_INFO("osm_localization: map origin (ENU) at %.7f, %.7f", fix->latitude, fix->longitude);
  }

  void onBuildings(const BuildingArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!msg->header.frame_id.empty() && msg->header.frame_id != node_params_.map_frame) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "osm_localization: osm/buildings in frame '%s', expected '%s'; ignored",
                            msg->header.frame_id.c_str(), node_params_.map_frame.c_str());
      return;
    }
    const size_t added =
        localizer_->addBuildings(buildingsFromMsg(*msg, origin_ ? &*origin_ : nullptr));
    if (added > 0)
      NODELET_DEBUG("osm_localization: %zu new buildings (%zu held)", added,
                    localizer_->numBuildings());
  }

  void onFix(const sensor_msgs::NavSatFixConstPtr& msg) {
    if (msg->status.status < sensor_msgs::NavSatStatus::STATUS_FIX) return;
    if (!inputs_.addFix({msg->header.stamp.toSec(), msg->latitude, msg->longitude, msg->altitude,
                         navSatFixStd(*msg)}))
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "osm_localization: gps/fix at %.3f has a non-finite position; ignored",
                            msg->header.stamp.toSec());
  }

  void onImu(const sensor_msgs::ImuConstPtr& msg) {
    if (msg->orientation_covariance[0] < 0.0) return;  // REP-145: no orientation
    const auto& q = msg->orientation;
    inputs_.addOrientation(msg->header.stamp.toSec(), Eigen::Quaterniond(q.w, q.x, q.y, q.z));
  }

  /// The prefiltered scan waits for the tracker's pose of the same stamp (onOdom).
  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_clouds_.push_back(msg);
    while (pending_clouds_.size() > 20) {
      pending_clouds_.pop_front();
      ++scans_without_odometry_;
    }
  }

  void onOdom(const nav_msgs::OdometryConstPtr& odom) {
    std::lock_guard<std::mutex> lock(mutex_);
    // Scans older than this pose never got one (the tracker rejected them): counted.
    while (!pending_clouds_.empty() &&
           pending_clouds_.front()->header.stamp < odom->header.stamp - ros::Duration(1e-4)) {
      pending_clouds_.pop_front();
      ++scans_without_odometry_;
    }
    if (pending_clouds_.empty() ||
        std::abs((pending_clouds_.front()->header.stamp - odom->header.stamp).toSec()) > 1e-4)
      return;  // its scan has not come (or was dropped): the next one will
    const sensor_msgs::PointCloud2ConstPtr cloud_msg = pending_clouds_.front();
    pending_clouds_.pop_front();
    if (!origin_) {
      NODELET_WARN_ONCE(
          "osm_localization: no osm/origin yet (osm_buffer sets it from the first "
          "fix); scans wait unlocalised");
      return;
    }
    auto cloud = std::make_shared<PointCloud>();
    std::string error;
    if (!fromPointCloud2(*cloud_msg, *cloud, &error)) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "osm_localization: scan at %.3f not convertible: %s",
                            cloud_msg->header.stamp.toSec(), error.c_str());
      return;
    }
    localize(odom->header.stamp, fromPoseMsg(odom->pose.pose), cloud);
  }

  // --- localisation ----------------------------------------------------------------------------
  void localize(const ros::Time& stamp, const Eigen::Isometry3d& odom_pose,
                const PointCloudConstPtr& cloud) {
    const auto t0 = std::chrono::steady_clock::now();
    const double t = stamp.toSec();
    std::optional<Eigen::Vector2d> gnss;
    std::optional<double> gnss_std;
    if (const auto fix = inputs_.gnssPositionAt(t)) {
      gnss = fix->xy;
      if (fix->std_xy > 0.0) gnss_std = fix->std_xy;
    }
    std::optional<double> yaw;
    if (const auto att = inputs_.attitudeAt(t)) yaw = att->yaw;
    const OsmLocalizationOutput out = localizer_->process(t, odom_pose, cloud, gnss, gnss_std, yaw);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    publish(stamp, odom_pose, out, ms);
    if (scans_without_odometry_ > reported_without_odometry_) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "osm_localization: %zu scans had no odometry pose (the tracker "
                            "rejected or dropped them); not localised",
                            scans_without_odometry_);
      reported_without_odometry_ = scans_without_odometry_;
    }
  }

  void publish(const ros::Time& stamp, const Eigen::Isometry3d& odom_pose,
               const OsmLocalizationOutput& out, double ms) {
    OsmLocalizationReport report;
    report.header.stamp = stamp;
    report.header.frame_id = node_params_.map_frame;
    report.status = toString(out.status);
    report.pose.pose = toPoseMsg(out.pose);
    const int idx[3] = {0, 1, 5};  // x, y, yaw in the 6×6 (x y z rx ry rz) layout
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        report.pose.covariance[idx[r] * 6 + idx[c]] = out.covariance(r, c);
    report.datum.x = out.datum.x();
    report.datum.y = out.datum.y();
    report.osm_attempted = out.osm_attempted;
    report.osm_outcome = out.osm_outcome;
    report.osm_fitness = out.osm_fitness;
    report.osm_accepted = static_cast<uint32_t>(localizer_->stats().osm_accepted);
    report.buildings = static_cast<uint32_t>(localizer_->numBuildings());
    report.time_ms = ms;
    status_pub_.publish(report);
    if (out.status == OsmLocalizationStatus::kUninitialized) return;

    nav_msgs::Odometry odom;
    odom.header = report.header;
    odom.child_frame_id = node_params_.base_link_frame;
    odom.pose = report.pose;
    odom_pub_.publish(odom);
    geometry_msgs::PoseStamped pose;
    pose.header = report.header;
    pose.pose = report.pose.pose;
    pose_pub_.publish(pose);
    if (!node_params_.publish_tf) return;
    geometry_msgs::TransformStamped tf;
    tf.header = report.header;
    tf.child_frame_id = node_params_.odom_frame;
    tf.transform = toTransformMsg(out.pose * odom_pose.inverse());
    tf_broadcaster_.sendTransform(tf);
  }

  OsmLocalizationNodeletParams node_params_;
  std::mutex mutex_;  ///< every callback (the manager may run them on several threads)
  std::unique_ptr<OsmLocalizer> localizer_;
  SensorInputs inputs_;
  std::optional<EnuConverter> origin_;
  std::deque<sensor_msgs::PointCloud2ConstPtr> pending_clouds_;
  size_t scans_without_odometry_ = 0, reported_without_odometry_ = 0;
  ros::Publisher odom_pub_, pose_pub_, status_pub_;
  ros::Subscriber cloud_sub_, odom_sub_, fix_sub_, imu_sub_, origin_sub_, buildings_sub_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::OsmLocalizationNodelet, nodelet::Nodelet)
