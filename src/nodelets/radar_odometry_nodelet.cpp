// RadarOdometryNodelet: radar/polar (sensor_msgs/Image, mono8, one row per azimuth, as mulran2bag
// writes it) -> RadarOdometryStream (radar_stream.h: checks, conversion, RadarSlam) -> radar/odom,
// TF radar_odom -> the image's frame, radar/path, radar/features (x y z power) and radar/status
// (diagnostic_msgs/DiagnosticArray, one entry per image). With loop/enabled also the back-end's
// TF radar_map -> radar_odom, radar/slam_path (corrected sweep poses) and radar/loops (the loop
// edges), and it feeds gps/fix (sensor_msgs/NavSatFix) and imu/data (sensor_msgs/Imu, the yaw
// rate) into the graph (gnss/enabled, imu/enabled). doc/radar.md "ROS: radar_odometry nodelet and
// radar.launch", "Radar SLAM through ROS", "GNSS and gyro through ROS".
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/radar/radar_drive.h"
#include "osm_graph_slam/radar/radar_stream.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {

class RadarOdometryNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    const RosParamReader reader(pnh);
    radar::RadarSlamParams slam_params;
    radar::RadarStreamParams stream_params;
    std::string error;
    if (!readParams(reader, node_params_, &error) ||
        !radar::readSlamParams(reader, slam_params, &error) ||
        !radar::readParams(reader, stream_params, &error)) {
      NODELET_ERROR("radar odometry NOT started (no subscription): %s", error.c_str());
      return;
    }
    stream_ = std::make_unique<radar::RadarOdometryStream>(slam_params, stream_params);
    odom_pub_ = nh.advertise<nav_msgs::Odometry>("radar/odom", 10);
    path_pub_ = nh.advertise<nav_msgs::Path>("radar/path", 1, true);
    features_pub_ = nh.advertise<sensor_msgs::PointCloud2>("radar/features", 2);
    status_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("radar/status", 10);
    if (stream_->loopsEnabled()) {
      slam_path_pub_ = nh.advertise<nav_msgs::Path>("radar/slam_path", 1, true);
      loops_pub_ = nh.advertise<visualization_msgs::MarkerArray>("radar/loops", 1, true);
    }
    sub_ = nh.subscribe("radar/polar", 10, &RadarOdometryNodelet::onImage, this);
    // GNSS and gyro feed the back-end only. The nodelet's callbacks (getNodeHandle: one queue,
    // one thread) never run concurrently, so the stream needs no lock.
    std::string nav;
    if (stream_->loopsEnabled() && slam_params.nav.gnss_enabled) {
      gps_sub_ = nh.subscribe("gps/fix", uint32_t(node_params_.nav_queue_size),
                              &RadarOdometryNodelet::onFix, this);
      nav += ", GNSS from " + gps_sub_.getTopic();
    }
    if (stream_->loopsEnabled() && slam_params.nav.imu_enabled) {
      imu_sub_ = nh.subscribe("imu/data", uint32_t(node_params_.nav_queue_size),
                              &RadarOdometryNodelet::onImu, this);
      nav += ", yaw rate from " + imu_sub_.getTopic();
    }
    const std::string loops = stream_->loopsEnabled() ? "on, TF " + node_params_.radar_map_frame +
                                                            " -> " + node_params_.radar_odom_frame
                                                      : "off";
    NODELET_INFO(
        "radar odometry: %s features, %d x %d images, max gap %.2f s, %s -> image frame; loop "
        "closure %s%s",
        slam_params.odometry.features.detector.c_str(), stream_params.layout.expected_bins,
        stream_params.layout.expected_azimuths, stream_params.max_gap,
        node_params_.radar_odom_frame.c_str(), loops.c_str(), nav.c_str());
  }

  /// NavSatFix -> RadarOdometryStream::addGnssFix: STATUS_NO_FIX is not a fix; the horizontal
  /// sigma from the covariance's east / north diagonal (the larger), unknown for
  /// COVARIANCE_TYPE_UNKNOWN (the stream uses input/gnss_unknown_sigma).
  void onFix(const sensor_msgs::NavSatFixConstPtr& msg) {
    const bool valid = msg->status.status >= sensor_msgs::NavSatStatus::STATUS_FIX;
    const double sigma =
        msg->position_covariance_type == sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN
            ? -1.0
            : std::sqrt(std::max(msg->position_covariance[0], msg->position_covariance[4]));
    std::lock_guard<std::mutex> lock(stream_mutex_);
    stream_->addGnssFix(int64_t(msg->header.stamp.toNSec()), msg->latitude, msg->longitude,
                        msg->altitude, sigma, valid);
  }

  /// Imu -> RadarOdometryStream::addYawRate: angular_velocity.z; REP-145 marks a message without
  /// rates by angular_velocity_covariance[0] = -1.
  void onImu(const sensor_msgs::ImuConstPtr& msg) {
    std::lock_guard<std::mutex> lock(stream_mutex_);
    stream_->addYawRate(int64_t(msg->header.stamp.toNSec()), msg->angular_velocity.z,
                        msg->angular_velocity_covariance[0] != -1.0);
  }

  void onImage(const sensor_msgs::ImageConstPtr& msg) {
    // The manager's worker threads may run the image and the navigation callbacks at once.
    std::lock_guard<std::mutex> lock(stream_mutex_);
    radar::PolarImageView view;
    view.data = msg->data.data();
    view.size = msg->data.size();
    view.rows = int(msg->height);
    view.cols = int(msg->width);
    view.step = msg->step;
    view.encoding = msg->encoding;
    const radar::RadarStreamResult r = stream_->process(view, int64_t(msg->header.stamp.toNSec()));
    const radar::RadarStreamCounters& c = stream_->counters();
    const double throttle = node_params_.warn_throttle_period;
    switch (r.event) {
      case radar::RadarStreamEvent::kBadImage:
        NODELET_WARN_THROTTLE(throttle, "radar/polar image dropped: %s (%lu so far)",
                              r.message.c_str(), (unsigned long)c.bad_images);
        break;
      case radar::RadarStreamEvent::kOutOfOrder:
        NODELET_WARN_THROTTLE(throttle, "radar/polar out of order: %s (%lu so far)",
                              r.message.c_str(), (unsigned long)c.out_of_order);
        break;
      case radar::RadarStreamEvent::kRestarted:  // rare: one line per gap
        NODELET_WARN("radar odometry: %s (gap %lu)", r.message.c_str(), (unsigned long)c.gaps);
        break;
      case radar::RadarStreamEvent::kProcessed:
        if (!r.step.ok)
          NODELET_WARN_THROTTLE(throttle,
                                "radar sweep at %.3f: no velocity estimate (%d matches, %d "
                                "inliers), constant velocity kept (%lu so far)",
                                msg->header.stamp.toSec(), r.step.matches, r.step.inliers,
                                (unsigned long)c.ransac_failures);
        break;
    }
    const std::string frame =
        msg->header.frame_id.empty() ? node_params_.radar_frame : msg->header.frame_id;
    if (r.has_step) {
      ros::Time stamp;
      stamp.fromNSec(uint64_t(r.time_ns));
      publishOdometry(stamp, frame, r.step);
      publishFeatures(stamp, frame, r.step.feature_set);
      if (stream_->loopsEnabled()) publishSlam(stamp, r);
      if (r.new_anchor) logAnchor();
      if (r.new_loops > 0) {
        const radar::RadarLoopStats& ls = stream_->slam().loopStats();
        NODELET_INFO("radar loop closed: keyframes %d - %d (%d accepted, %d candidates)",
                     stream_->slam().loops().back().from, stream_->slam().loops().back().to,
                     ls.accepted, ls.candidates);
      }
    }
    publishStatus(msg->header.stamp, frame, r);
  }

  /// Once: the ENU frame of the fixes (origin: the first valid fix) in radar_map.
  void logAnchor() {
    const std::optional<Eigen::Isometry2d> T = stream_->slam().mapFromEnu();
    const std::optional<EnuConverter>& enu = stream_->enu();
    if (!T || !enu) return;
    const radar::RadarNavStats& n = stream_->slam().navStats();
    NODELET_INFO(
        "radar GNSS anchor set: ENU (origin %.7f, %.7f, %.2f m) -> %s: translation (%.2f, %.2f) "
        "m, yaw %.2f deg; %d fixes, %d GNSS edges",
        enu->originLat(), enu->originLon(), enu->originAlt(), node_params_.radar_map_frame.c_str(),
        T->translation().x(), T->translation().y(),
        std::atan2(T->linear()(1, 0), T->linear()(0, 0)) * 180.0 / M_PI, n.gnss_fixes,
        n.gnss_edges);
  }

  /// The radar pose at the sweep's mid time (the time the odometry keys it by).
  void publishOdometry(const ros::Time& stamp, const std::string& frame,
                       const radar::RadarOdometryStep& step) {
    const Eigen::Isometry3d pose = radar::planarTo3d(step.pose);
    boost::shared_ptr<nav_msgs::Odometry> odom(new nav_msgs::Odometry);
    odom->header.stamp = stamp;
    odom->header.frame_id = node_params_.radar_odom_frame;
    odom->child_frame_id = frame;
    odom->pose.pose = toPoseMsg(pose);
    odom->twist.twist.linear.x = step.velocity.x();  // in the child frame
    odom->twist.twist.linear.y = step.velocity.y();
    odom->twist.twist.angular.z = step.velocity.z();
    odom_pub_.publish(boost::shared_ptr<const nav_msgs::Odometry>(odom));

    geometry_msgs::PoseStamped ps;
    ps.header = odom->header;
    ps.pose = odom->pose.pose;
    path_.header = odom->header;
    path_.poses.push_back(ps);
    path_pub_.publish(path_);

    if (node_params_.publish_tf) {
      geometry_msgs::TransformStamped tf;
      tf.header = odom->header;
      tf.child_frame_id = frame;
      tf.transform = toTransformMsg(pose);
      tf_broadcaster_.sendTransform(tf);
    }
  }

  /// The back-end: TF radar_map -> radar_odom (every sweep), radar/slam_path (appended; rebuilt
  /// from the corrected poses when an optimisation moved them: a loop, the GNSS anchor, GNSS
  /// edges) and radar/loops (when a loop is accepted).
  void publishSlam(const ros::Time& stamp, const radar::RadarStreamResult& r) {
    geometry_msgs::TransformStamped tf;
    tf.header.stamp = stamp;
    tf.header.frame_id = node_params_.radar_map_frame;
    tf.child_frame_id = node_params_.radar_odom_frame;
    tf.transform = toTransformMsg(radar::planarTo3d(r.map_to_odometry));
    tf_broadcaster_.sendTransform(tf);

    slam_path_.header.stamp = stamp;
    slam_path_.header.frame_id = node_params_.radar_map_frame;
    auto poseStamped = [this](int64_t time_ns, const Eigen::Isometry2d& pose) {
      geometry_msgs::PoseStamped ps;
      ps.header.stamp.fromNSec(uint64_t(time_ns));
      ps.header.frame_id = node_params_.radar_map_frame;
      ps.pose = toPoseMsg(radar::planarTo3d(pose));
      return ps;
    };
    if (r.new_loops > 0 || r.optimised) {
      const radar::RadarSlam& slam = stream_->slam();
      const std::vector<Eigen::Isometry2d> poses = slam.sweepPoses();
      const std::vector<double>& times = slam.sweepTimes();
      slam_path_.poses.clear();
      slam_path_.poses.reserve(poses.size());
      for (size_t i = 0; i < poses.size() && i < times.size(); ++i)
        slam_path_.poses.push_back(poseStamped(stream_->toInputTime(times[i]), poses[i]));
      if (r.new_loops > 0) publishLoops(stamp);
    } else {
      slam_path_.poses.push_back(poseStamped(r.time_ns, r.corrected));
    }
    slam_path_pub_.publish(slam_path_);
  }

  /// One LINE_LIST of the accepted loop edges between the corrected keyframe positions.
  void publishLoops(const ros::Time& stamp) {
    visualization_msgs::MarkerArray array;
    visualization_msgs::Marker m;
    m.header.stamp = stamp;
    m.header.frame_id = node_params_.radar_map_frame;
    m.ns = "radar_loops";
    m.id = 0;
    m.type = visualization_msgs::Marker::LINE_LIST;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.scale.x = 0.4;
    m.color.r = 1.0f;
    m.color.g = 0.2f;
    m.color.b = 0.2f;
    m.color.a = 1.0f;
    for (const auto& segment : stream_->slam().loopSegments())
      for (const Eigen::Vector2d& p : {segment.first, segment.second}) {
        geometry_msgs::Point q;
        q.x = p.x();
        q.y = p.y();
        m.points.push_back(q);
      }
    array.markers.push_back(m);
    loops_pub_.publish(array);
  }

  /// The sweep's features in the image frame (each as seen at its own row time), z = 0.
  void publishFeatures(const ros::Time& stamp, const std::string& frame,
                       const radar::RadarFeatureSet& set) {
    if (features_pub_.getNumSubscribers() == 0) return;
    boost::shared_ptr<sensor_msgs::PointCloud2> cloud(new sensor_msgs::PointCloud2);
    cloud->header.stamp = stamp;
    cloud->header.frame_id = frame;
    sensor_msgs::PointCloud2Modifier modifier(*cloud);
    modifier.setPointCloud2Fields(
        4, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32, "z",
        1, sensor_msgs::PointField::FLOAT32, "power", 1, sensor_msgs::PointField::FLOAT32);
    modifier.resize(set.features.size());
    sensor_msgs::PointCloud2Iterator<float> x(*cloud, "x"), y(*cloud, "y"), z(*cloud, "z"),
        power(*cloud, "power");
    for (const radar::RadarFeature& f : set.features) {
      *x = float(f.point.x());
      *y = float(f.point.y());
      *z = 0.0f;
      *power = f.power;
      ++x, ++y, ++z, ++power;
    }
    features_pub_.publish(boost::shared_ptr<const sensor_msgs::PointCloud2>(cloud));
  }

  void publishStatus(const ros::Time& stamp, const std::string& frame,
                     const radar::RadarStreamResult& r) {
    const radar::RadarStreamCounters& c = stream_->counters();
    boost::shared_ptr<diagnostic_msgs::DiagnosticArray> array(new diagnostic_msgs::DiagnosticArray);
    array->header.stamp = stamp;
    array->header.frame_id = frame;
    diagnostic_msgs::DiagnosticStatus s;
    s.name = "radar_odometry";
    s.hardware_id = frame;
    const bool fine = r.event == radar::RadarStreamEvent::kProcessed && r.step.ok;
    s.level =
        fine ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN;
    s.message = r.message.empty() ? (r.step.ok ? "ok" : "no velocity estimate (constant velocity)")
                                  : r.message;
    auto add = [&s](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      s.values.push_back(kv);
    };
    auto num = [](double v) {
      char text[32];
      std::snprintf(text, sizeof(text), "%.3f", v);
      return std::string(text);
    };
    add("event", radar::toString(r.event));
    add("received", std::to_string(c.received));
    add("processed", std::to_string(c.processed));
    add("bad_images", std::to_string(c.bad_images));
    add("out_of_order", std::to_string(c.out_of_order));
    add("gaps", std::to_string(c.gaps));
    add("ransac_failures", std::to_string(c.ransac_failures));
    add("features", std::to_string(r.has_step ? r.step.features : 0));
    add("matches", std::to_string(r.has_step ? r.step.matches : 0));
    add("inliers", std::to_string(r.has_step ? r.step.inliers : 0));
    add("rms_error_m", num(r.has_step ? r.step.rms_error : 0.0));
    add("ms_per_scan", num(c.ms_last));
    add("ms_per_scan_mean", num(c.ms_mean));
    if (stream_->loopsEnabled()) {
      const radar::RadarSlam& slam = stream_->slam();
      const radar::RadarLoopStats& ls = slam.loopStats();
      add("keyframes", std::to_string(slam.numKeyframes()));
      add("loops_accepted", std::to_string(ls.accepted));
      add("loop_candidates", std::to_string(ls.candidates));
      add("loops_rejected_registration", std::to_string(ls.rejected_registration));
      add("loops_rejected_gate", std::to_string(ls.rejected_gate));
      add("loop_ms_per_keyframe", num(c.ms_loop_per_keyframe));
      add("optimisations", std::to_string(ls.optimisations));
      // GNSS and gyro: what the stream took (RadarStreamCounters) and what the graph made of it
      // (RadarNavStats).
      const radar::RadarNavStats& n = slam.navStats();
      add("gnss_received", std::to_string(c.gnss_received));
      add("gnss_invalid", std::to_string(c.gnss_invalid));
      add("gnss_unknown_sigma", std::to_string(c.gnss_unknown_sigma));
      add("gnss_fixes", std::to_string(n.gnss_fixes));
      add("gnss_rejected_sigma", std::to_string(n.gnss_rejected_sigma));
      add("gnss_out_of_order", std::to_string(n.gnss_out_of_order));
      add("gnss_edges", std::to_string(n.gnss_edges));
      add("gnss_anchored", n.anchored ? "true" : "false");
      add("imu_received", std::to_string(c.imu_received));
      add("imu_invalid", std::to_string(c.imu_invalid));
      add("imu_samples", std::to_string(n.imu_samples));
      add("imu_out_of_order", std::to_string(n.imu_out_of_order));
      add("imu_edges", std::to_string(n.imu_edges));
      add("imu_missing", std::to_string(n.imu_missing));
      add("nav_buffered", std::to_string(c.nav_buffered));
      add("nav_dropped_early", std::to_string(c.nav_dropped_early));
    }
    array->status.push_back(s);
    status_pub_.publish(boost::shared_ptr<const diagnostic_msgs::DiagnosticArray>(array));
  }

  RadarOdometryNodeletParams node_params_;  ///< frames, TF, throttling (nodelet_params.h)
  std::unique_ptr<radar::RadarOdometryStream> stream_;
  std::mutex stream_mutex_;  ///< guards stream_ (image and navigation callbacks)
  nav_msgs::Path path_, slam_path_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  ros::Publisher odom_pub_, path_pub_, features_pub_, status_pub_, slam_path_pub_, loops_pub_;
  ros::Subscriber sub_, gps_sub_, imu_sub_;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::RadarOdometryNodelet, nodelet::Nodelet)
