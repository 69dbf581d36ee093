// ScanMatchingNodelet: filtered_points (base_link) -> KeyframeTracker -> odom, TF odom->base_link,
// keyframe (new keyframes only), scan_matching_status (every scan) and tracking_health_marker
// (an rviz text above the vehicle: OK / RECOVERED / LOST, on changes and with each keyframe).
// With `tracker: multi_cue` it also subscribes to velodyne_points, the raw scans in the LiDAR's
// frame, which the multi-cue tracker projects at full resolution (doc/multi_cue.md).
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/Marker.h>
#include <pluginlib/class_list_macros.hpp>

#include <deque>
#include <memory>
#include <mutex>
#include <stdexcept>

#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/ScanMatchingStatus.h"
#include "osm_graph_slam/odometry/imu_orientation_buffer.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/odometry/params_io.h"
#include "osm_graph_slam/odometry/tracking_health.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/keyframe_conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/ros_param_reader.h"
#include "osm_graph_slam/ros/sensor_mount_lookup.h"
#include "osm_graph_slam/slam/keyframe_input.h"

namespace osm_graph_slam {

class ScanMatchingNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    readParams(RosParamReader(pnh), node_params_);  // defaults: nodelet_params.h
    KeyframeTrackerParams params;
    readParams(RosParamReader(pnh), params);
    // A wrong tracker or guess is a mistake in the configuration: stop here, saying which.
    if (const std::string why = params.validate(); !why.empty()) {
      NODELET_FATAL("scan_matching: %s", why.c_str());
      throw std::invalid_argument("scan_matching: " + why);
    }
    try {
      tracker_ = std::make_unique<KeyframeTracker>(params);
    } catch (const std::exception& e) {
      NODELET_ERROR("%s; falling back to fast_gicp", e.what());
      KeyframeTrackerParams fallback = params;
      fallback.registration.method = "fast_gicp";
      tracker_ = std::make_unique<KeyframeTracker>(fallback);
    }
    health_ = std::make_unique<TrackingHealth>(params.lost_track_after);
    const bool multi_cue = params.tracker == "multi_cue";
    if (params.deskew || multi_cue)  // multi_cue: its image is the LiDAR's view
      mount_ = std::make_unique<SensorMountLookup>(nh, node_params_.base_link_frame,
                                                   node_params_.sensor_frame);
    odom_pub_ = nh.advertise<nav_msgs::Odometry>("odom", 10);
    keyframe_pub_ = nh.advertise<KeyFrame>("keyframe", 10);
    status_pub_ = nh.advertise<ScanMatchingStatus>("scan_matching_status", 10);
    // Latched: rviz started later still shows the current tracking health.
    marker_pub_ = nh.advertise<visualization_msgs::Marker>("tracking_health_marker", 1, true);
    sub_ = nh.subscribe("filtered_points", 5, &ScanMatchingNodelet::onCloud, this);
    // The IMU's orientation (or integrated rates) for the imu guesses and the recovery; its
    // frame is taken to be base_link (kitti2bag and mulran2bag mount it there).
    imu_sub_ = nh.subscribe("imu/data", 200, &ScanMatchingNodelet::onImu, this);
    if (multi_cue) raw_sub_ = nh.subscribe("velodyne_points", 5, &ScanMatchingNodelet::onRaw, this);
    if (node_params_.imu_wait_timeout > 0.0)
      pending_timer_ =
          nh.createWallTimer(ros::WallDuration(0.05), &ScanMatchingNodelet::onPendingTimer, this);
    NODELET_INFO("scan matching: %s, keyframe every %.2f m / %.3f rad / %.1f s, %s -> %s%s",
                 multi_cue ? "multi_cue" : params.registration.method.c_str(),
                 params.keyframe_delta_trans, params.keyframe_delta_angle,
                 params.keyframe_delta_time, node_params_.odom_frame.c_str(),
                 node_params_.base_link_frame.c_str(), params.deskew ? ", deskewing" : "");
  }

  // --- the raw scans (multi_cue) -------------------------------------------------------------
  // The prefilter publishes filtered_points with the raw scan's stamp a few milliseconds after
  // the raw scan arrived here, so the raw scan of a filtered one is found by its stamp among
  // the last few.
  void onRaw(const sensor_msgs::PointCloud2ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(raw_mutex_);
    raw_.push_back(msg);
    while (raw_.size() > kRawScansKept) raw_.pop_front();
  }

  /// The raw scan stamped `stamp`, converted; null when it did not arrive (the tracker then
  /// projects the filtered scan and says so once).
  PointCloudConstPtr rawScanAt(const ros::Time& stamp) {
    sensor_msgs::PointCloud2ConstPtr msg;
    {
      std::lock_guard<std::mutex> lock(raw_mutex_);
      for (const auto& m : raw_)
        if (m->header.stamp == stamp) msg = m;
    }
    if (!msg) return nullptr;
    if (!msg->header.frame_id.empty() && msg->header.frame_id != node_params_.sensor_frame)
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "velodyne_points in frame '%s', expected sensor_frame '%s'",
                            msg->header.frame_id.c_str(), node_params_.sensor_frame.c_str());
    PointCloudPtr cloud = std::make_shared<PointCloud>();
    std::string error;
    if (!fromPointCloud2(*msg, *cloud, &error)) return nullptr;
    return cloud;
  }

  void onImu(const sensor_msgs::ImuConstPtr& msg) {
    addImuSample(msg);
    onImuSample();
  }

  void addImuSample(const sensor_msgs::ImuConstPtr& msg) {
    const double stamp = msg->header.stamp.toSec();
    std::lock_guard<std::mutex> lock(imu_mutex_);
    const double jump = tracker_->params().restart_after_jump_back;
    if (imu_.size() > 0 && jump > 0.0 && stamp < imu_.newestStamp() - jump) {
      // A looped bag: the buffer would refuse every later sample as out of order.
      NODELET_INFO("imu/data jumped back %.1f s in time: IMU buffer cleared",
                   imu_.newestStamp() - stamp);
      imu_.clear();
    }
    // An IMU too slow (or with gaps) for the imu guess: scans between two samples get no
    // orientation and silently fall back to constant velocity. Measured on the samples' stamps,
    // not on their arrival, so an IMU that arrives a little after the scans is not reported.
    const double dt = imu_.size() > 0 ? stamp - imu_.newestStamp() : 0.0;
    if (dt > 2.0 * imu_.maxGap())
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "imu/data: %.2f s between samples (up to %.3f), more than %.2f s: "
                            "scans between them get no IMU orientation (constant-velocity guess)",
                            dt, stamp, 2.0 * imu_.maxGap());
    if (msg->orientation_covariance[0] >= 0.0) {  // REP-145: -1 = no orientation
      const auto& q = msg->orientation;
      imu_.addOrientation(stamp, Eigen::Quaterniond(q.w, q.x, q.y, q.z));
    } else {
      const auto& w = msg->angular_velocity;
      imu_.addAngularVelocity(stamp, Eigen::Vector3d(w.x, w.y, w.z));
    }
  }

  void onImuSample() {
    std::lock_guard<std::mutex> lock(track_mutex_);
    if (pending_.msg && imuReached(pending_.msg->header.stamp.toSec())) releasePending();
  }

  std::optional<Eigen::Quaterniond> imuOrientationAt(double stamp) {
    std::lock_guard<std::mutex> lock(imu_mutex_);
    return imu_.orientationAt(stamp);
  }

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    PointCloudPtr cloud = std::make_shared<PointCloud>();
    std::string error;
    std::lock_guard<std::mutex> lock(track_mutex_);
    if (!fromPointCloud2(*msg, *cloud, &error)) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period, "dropping scan: %s", error.c_str());
      if (const auto event = health_->updateRejected(msg->header.stamp.toSec(), error))
        NODELET_WARN("%s", event->message.c_str());
      publishHealthMarker(msg->header.stamp, false);
      return;
    }
    if (!msg->header.frame_id.empty() && msg->header.frame_id != node_params_.base_link_frame) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "filtered_points in frame '%s', expected '%s'",
                            msg->header.frame_id.c_str(), node_params_.base_link_frame.c_str());
    }
    releasePending();  // the next scan came first: the IMU is late or absent
    if (node_params_.imu_wait_timeout > 0.0 && !imuReached(msg->header.stamp.toSec())) {
      pending_ = {msg, cloud, ros::WallTime::now()};
      return;
    }
    track(msg, cloud);
  }

  // --- waiting for the IMU ------------------------------------------------------------------
  // The IMU and the scans reach the nodelet on separate queues. A scan tracked before the IMU
  // sample after its stamp arrived got the sample before it instead of an interpolation (at
  // KITTI's 10 Hz OXTS up to 0.1 s old: 1-2 deg in a turn), so a replay under load tracked other
  // keyframes than on an idle machine. A scan therefore waits for that sample, for the next scan
  // or for imu_wait_timeout, whichever comes first.
  struct PendingScan {
    sensor_msgs::PointCloud2ConstPtr msg;
    PointCloudPtr cloud;
    ros::WallTime since;
  };

  /// Whether the IMU buffer reaches `stamp` (or holds nothing: no IMU to wait for).
  bool imuReached(double stamp) {
    std::lock_guard<std::mutex> lock(imu_mutex_);
    return imu_.size() == 0 || imu_.newestStamp() >= stamp;
  }

  void releasePending() {  // track_mutex_ held
    if (!pending_.msg) return;
    PendingScan scan = std::move(pending_);
    pending_ = {};
    track(scan.msg, scan.cloud);
  }

  void onPendingTimer(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(track_mutex_);
    if (pending_.msg &&
        (ros::WallTime::now() - pending_.since).toSec() >= node_params_.imu_wait_timeout)
      releasePending();
  }

  void track(const sensor_msgs::PointCloud2ConstPtr& msg, const PointCloudPtr& cloud) {
    const double stamp = msg->header.stamp.toSec();
    warnOnGap(stamp);
    if (mount_)
      if (const auto mount = mount_->get()) tracker_->setSensorToBase(*mount);
    const PointCloudConstPtr raw = raw_sub_ ? rawScanAt(msg->header.stamp) : nullptr;
    const TrackResult result = tracker_->track(stamp, cloud, imuOrientationAt(stamp), raw);
    if (!result.notice.empty()) NODELET_WARN("%s", result.notice.c_str());  // each once
    // Lost and recovered are each one line, whatever the throttling.
    if (const auto event = health_->update(msg->header.stamp.toSec(), result))
      NODELET_WARN("%s", event->message.c_str());
    publishStatus(msg->header.stamp, result);
    publishHealthMarker(msg->header.stamp, result.new_keyframe);
    if (!result.has_pose()) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period, "scan at %.3f ignored: %s",
                            msg->header.stamp.toSec(), result.message.c_str());
      return;
    }
    if (result.failed() && result.status != TrackStatus::kRestarted) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "scan at %.3f: %s (constant-velocity prediction kept)",
                            msg->header.stamp.toSec(), result.message.c_str());
    }
    publishOdometry(msg->header.stamp, result.pose);
    if (result.new_keyframe) publishKeyframe(*msg, result);
  }

  /// One line per gap in the scans longer than the motion model extrapolates over.
  void warnOnGap(double stamp) {
    const double gap = stamp - last_scan_stamp_;
    if (last_scan_stamp_ > 0.0 && gap > tracker_->params().max_prediction_gap)
      NODELET_WARN("no scan for %.1f s before %.3f: the motion guess extrapolates %.1f s of it",
                   gap, stamp, tracker_->params().max_prediction_gap);
    last_scan_stamp_ = stamp;
  }

  void publishOdometry(const ros::Time& stamp, const Eigen::Isometry3d& pose) {
    boost::shared_ptr<nav_msgs::Odometry> odom(new nav_msgs::Odometry);
    odom->header.stamp = stamp;
    odom->header.frame_id = node_params_.odom_frame;
    odom->child_frame_id = node_params_.base_link_frame;
    odom->pose.pose = toPoseMsg(pose);
    odom_pub_.publish(boost::shared_ptr<const nav_msgs::Odometry>(odom));
    if (node_params_.publish_tf) {
      geometry_msgs::TransformStamped tf;
      tf.header = odom->header;
      tf.child_frame_id = node_params_.base_link_frame;
      tf.transform = toTransformMsg(pose);
      tf_broadcaster_.sendTransform(tf);
    }
  }

  void publishKeyframe(const sensor_msgs::PointCloud2& cloud, const TrackResult& result) {
    const Keyframe& kf = tracker_->keyframe();
    boost::shared_ptr<KeyFrame> msg(new KeyFrame);
    toKeyFrameMsg(keyframeInput(kf, result), *msg);
    msg->header.stamp = cloud.header.stamp;
    msg->header.frame_id = node_params_.odom_frame;
    msg->recovery_gap = result.gap;
    if (kf.cloud && tracker_->params().deskew) {
      // The keyframe holds the deskewed scan: walls, loops and the map must get that one.
      toPointCloud2(*kf.cloud, msg->cloud);
      msg->cloud.header = cloud.header;
    } else {
      msg->cloud = cloud;
    }
    keyframe_pub_.publish(boost::shared_ptr<const KeyFrame>(msg));
  }

  void publishStatus(const ros::Time& stamp, const TrackResult& result) {
    boost::shared_ptr<ScanMatchingStatus> msg(new ScanMatchingStatus);
    msg->header.stamp = stamp;
    msg->header.frame_id = node_params_.odom_frame;
    msg->has_converged = result.registration.converged;
    msg->failed = result.failed();
    msg->method = tracker_->params().tracker == "multi_cue"
                      ? "multi_cue"
                      : tracker_->params().registration.method;
    msg->fitness = result.registration.fitness;
    msg->iterations = result.registration.iterations;
    msg->time_ms = result.registration.time_ms;
    msg->keyframe_id = result.keyframe_id;
    msg->new_keyframe = result.new_keyframe;
    msg->relative_pose = toTransformMsg(result.relative_to_keyframe);
    msg->message = result.failed() ? std::string(toString(result.status)) + ": " + result.message
                                   : std::string(toString(result.status));
    const TrackingStats health = health_->stats();
    msg->tracking_state = result.status == TrackStatus::kRestarted ? "restarted"
                          : result.reanchored                      ? "recovered"
                                                                   : toString(health_->state());
    msg->failed_matches = static_cast<uint32_t>(health.failed_matches);
    msg->lost_events = static_cast<uint32_t>(health.lost_events);
    msg->time_since_keyframe = health_->timeSinceKeyframe();
    msg->restarts = static_cast<uint32_t>(health.restarts);
    msg->rejected_scans = static_cast<uint32_t>(health.rejected_scans);
    status_pub_.publish(boost::shared_ptr<const ScanMatchingStatus>(msg));
  }

  /// The tracking-health label as a text above base_link (frame-locked, so it follows the
  /// vehicle between updates); the core decides what it says and when it is worth sending.
  void publishHealthMarker(const ros::Time& stamp, bool new_keyframe) {
    const auto label = health_display_.update(stamp.toSec(), *health_, new_keyframe);
    if (!label) return;
    boost::shared_ptr<visualization_msgs::Marker> m(new visualization_msgs::Marker);
    m->header.stamp = stamp;
    m->header.frame_id = node_params_.base_link_frame;
    m->ns = "tracking_health";
    m->id = 0;
    m->type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    m->action = visualization_msgs::Marker::ADD;
    m->pose.position.z = 4.0;  // [m] above base_link
    m->pose.orientation.w = 1.0;
    m->scale.z = 1.2;  // [m] text height
    m->color.r = label->r;
    m->color.g = label->g;
    m->color.b = label->b;
    m->color.a = 1.0;
    m->frame_locked = true;
    m->text = label->text;
    marker_pub_.publish(boost::shared_ptr<const visualization_msgs::Marker>(m));
  }

  ScanMatchingNodeletParams node_params_;  ///< frames, rates, TF (nodelet_params.h)
  std::unique_ptr<KeyframeTracker> tracker_;
  std::unique_ptr<TrackingHealth> health_;
  TrackingHealthDisplay health_display_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  std::unique_ptr<SensorMountLookup> mount_;  ///< only when deskewing
  ros::Publisher odom_pub_, keyframe_pub_, status_pub_, marker_pub_;
  ros::Subscriber sub_, imu_sub_, raw_sub_;
  static constexpr size_t kRawScansKept = 10;
  std::mutex raw_mutex_;
  std::deque<sensor_msgs::PointCloud2ConstPtr> raw_;  ///< the last raw scans (multi_cue)
  std::mutex imu_mutex_;                              ///< after track_mutex_ when both are held
  ImuOrientationBuffer imu_;
  std::mutex track_mutex_;  ///< the tracker and pending_: scans and IMU samples call in
  PendingScan pending_;     ///< a scan waiting for its IMU sample (msg null: none)
  ros::WallTimer pending_timer_;
  double last_scan_stamp_ = 0.0;  ///< [s] of the last scan received (0 before any)
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::ScanMatchingNodelet, nodelet::Nodelet)
