// LocalizationNodelet: localisation on a saved map package (ART-SLAM LOC, doc/localization.md).
//   filtered_points (base_link) + imu/data (gyro, accelerometer) -> Localizer (pose UKF +
//   scan-to-map registration, global re-localisation) -> odom (base_link in map, with covariance),
//   localization/status (every scan), TF map -> odom (and odom -> base_link from the filter's own
//   dead reckoning unless another odometry publishes it), localization/map_points (latched).
//   initialpose (rviz "2D Pose Estimate", PoseWithCovarianceStamped in the map frame) restarts the
//   filter there. Without ~initial_pose the first scans are localised globally (Scan Context).
//   With ~stop_when_mapping (a hand-over, graph_backend ~handover) it stops once slam/mapping
//   says the SLAM back-end maps: from then on graph_backend publishes map -> odom.
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Bool.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <pluginlib/class_list_macros.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "osm_graph_slam/LocalizationReport.h"
#include "osm_graph_slam/cloud/map_cloud.h"
#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/imu_reading_buffer.h"
#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/localization/map_frames.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/ros_param_reader.h"
#include "osm_graph_slam/ros/sensor_mount_lookup.h"
#include "osm_graph_slam/ros/wall_matching_params.h"

namespace osm_graph_slam {

class LocalizationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    readParams(RosParamReader(pnh), node_params_);  // defaults: nodelet_params.h
    const std::string map_dir = node_params_.map_dir, osm_file = node_params_.osm_file;
    std::vector<double> initial;
    pnh.param("initial_pose", initial, std::vector<double>());
    LocalizationParams params;
    readParams(RosParamReader(pnh), params);

    status_pub_ = nh.advertise<LocalizationReport>("localization/status", 10);
    odom_pub_ = nh.advertise<nav_msgs::Odometry>("odom", 10);
    map_pub_ = nh.advertise<sensor_msgs::PointCloud2>("localization/map_points", 1, true);
    if (params.deskew)
      mount_ = std::make_unique<SensorMountLookup>(nh, node_params_.base_link_frame,
                                                   node_params_.sensor_frame);
    if (!node_params_.publish_odom_tf) {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh);
    }

    if (map_dir.empty()) {
      // OSM-only localisation is another nodelet (osm_localization): say where to find it.
      NODELET_ERROR(
          "localization: no map_dir given%s; localisation needs a map package "
          "(offline_slam --output DIR writes DIR/map_package)",
          osm_file.empty() ? ""
                           : " (for localisation from OSM alone use "
                             "launch/osm_localization.launch)");
    } else {
      auto map = std::make_shared<MapPackage>();
      std::string error;
      const auto t0 = std::chrono::steady_clock::now();
      if (!loadMapPackage(map_dir, *map, &error)) {
        NODELET_ERROR("localization: %s", error.c_str());
      } else {
        try {
          localizer_ = std::make_unique<Localizer>(params, map);
          map_ = map;
          enableOsmWalls();
        } catch (const std::exception& e) {
          NODELET_ERROR("localization: %s", e.what());
        }
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        NODELET_INFO("localization: map %s, %zu keyframes, %zu points (ready in %.1f s), %s",
                     map_dir.c_str(), map->keyframes.size(), map->map_cloud->size(), s,
                     params.registration.method.c_str());
        if (localizer_) {
          const LocalizationStats& st = localizer_->stats();
          NODELET_INFO(
              "localization: global search limits learnt from the map: Scan Context %.3f, "
              "overlap %.3f (own places %.3f over %zu, impostors %.3f over %zu%s; %.1f s)",
              st.global_descriptor_limit, st.global_overlap_limit, st.global_overlap_own_low,
              st.global_overlap_own, st.global_overlap_impostor_high, st.global_overlap_impostors,
              st.global_overlap_limit > params.global_min_overlap ? "" : "; the floor stays",
              st.global_overlap_learn_ms / 1000.0);
        }
        if (!osm_file.empty())
          NODELET_WARN(
              "localization: osm_file is not used here (the map package's corrected "
              "buildings are in the map; from OSM alone: launch/osm_localization.launch)");
        publishMapPoints();
      }
    }
    if (localizer_ && !initial.empty()) {
      if (initial.size() != 3) {
        NODELET_ERROR(
            "localization: initial_pose must be [x, y, yaw] (map frame, m, rad); "
            "localising globally instead");
      } else {
        pending_initial_ = mapPoseFromXyYaw(*map_, initial[0], initial[1], initial[2]);
        NODELET_INFO("localization: initial pose %.2f %.2f %.3f", initial[0], initial[1],
                     initial[2]);
      }
    } else if (localizer_) {
      NODELET_INFO("localization: no initial pose, localising globally (Scan Context)");
    }
    cloud_sub_ = nh.subscribe("filtered_points", 5, &LocalizationNodelet::onCloud, this);
    imu_sub_ = nh.subscribe("imu/data", 1000, &LocalizationNodelet::onImu, this);
    if (node_params_.use_gnss && map_)
      gnss_sub_ = nh.subscribe("gps/fix", 10, &LocalizationNodelet::onGnssFix, this);
    initial_sub_ = nh.subscribe("initialpose", 2, &LocalizationNodelet::onInitialPose, this);
    if (node_params_.stop_when_mapping)
      mapping_sub_ = nh.subscribe("slam/mapping", 1, &LocalizationNodelet::onMapping, this);
  }

  void onMapping(const std_msgs::BoolConstPtr& msg) {
    if (!msg->data || stopped_.exchange(true)) return;
    NODELET_INFO(
        "localization: the SLAM back-end maps from here on (slam/mapping): localisation stops, "
        "graph_backend publishes %s -> %s",
        node_params_.map_frame.c_str(), node_params_.odom_frame.c_str());
  }

  /// Global localisation also searches the map package's buildings with the scan's walls
  /// (global_osm_walls), with the SLAM pipeline's wall extraction and line matcher.
  void enableOsmWalls() {
    bool found = false;
    const WallMatchingParams w = readWallMatchingParams(node_params_.line_extraction_ns,
                                                        node_params_.line_matcher_ns, &found);
    const size_t buildings = localizer_->enableOsmWalls(w.walls, w.segments, w.matcher);
    if (buildings == 0) return;
    NODELET_INFO(
        "localization: global search also matches the scan's walls with %zu buildings "
        "of the map package%s",
        buildings, found ? "" : " (wall and matcher parameters: built-in defaults)");
  }

  void publishMapPoints() {
    const PointCloudPtr cloud =
        node_params_.map_points_voxel > 0.0
            ? mergeClouds({{Eigen::Isometry3d::Identity(), map_->map_cloud}},
                          node_params_.map_points_voxel)
            : std::make_shared<PointCloud>(*map_->map_cloud);
    boost::shared_ptr<sensor_msgs::PointCloud2> msg(new sensor_msgs::PointCloud2);
    toPointCloud2(*cloud, *msg);
    msg->header.frame_id = node_params_.map_frame;
    msg->header.stamp = ros::Time::now();
    map_pub_.publish(boost::shared_ptr<const sensor_msgs::PointCloud2>(msg));
  }

  void onImu(const sensor_msgs::ImuConstPtr& msg) {
    // The IMU's frame is taken to be base_link (kitti2bag and mulran2bag mount it there).
    const auto& w = msg->angular_velocity;
    const auto& a = msg->linear_acceleration;
    const double stamp = msg->header.stamp.toSec();
    std::lock_guard<std::mutex> lock(mutex_);
    // REP-145: a covariance starting with -1 marks a quantity the IMU does not give.
    if (msg->angular_velocity_covariance[0] != -1.0)
      gyro_.add(stamp, Eigen::Vector3d(w.x, w.y, w.z));
    if (msg->linear_acceleration_covariance[0] != -1.0)
      accel_.add(stamp, Eigen::Vector3d(a.x, a.y, a.z));
  }

  /// A fix in the map's ENU frame: checks the tracked pose and global answers, never corrects.
  void onGnssFix(const sensor_msgs::NavSatFixConstPtr& msg) {
    if (msg->status.status < sensor_msgs::NavSatStatus::STATUS_FIX ||
        !std::isfinite(msg->latitude) || !std::isfinite(msg->longitude))
      return;
    if (!map_enu_) map_enu_.emplace(map_->origin_lat, map_->origin_lon, map_->origin_alt);
    const Eigen::Vector3d enu = map_enu_->toEnu(msg->latitude, msg->longitude, msg->altitude);
    double std = 0.0;
    if (msg->position_covariance_type != sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN)
      std = std::sqrt(std::max(msg->position_covariance[0], msg->position_covariance[4]));
    std::lock_guard<std::mutex> lock(mutex_);
    pending_gnss_ = GnssFix{msg->header.stamp.toSec(), enu.head<2>(), std};
  }

  void onInitialPose(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    if (!map_) return;
    if (!msg->header.frame_id.empty() && msg->header.frame_id != node_params_.map_frame) {
      NODELET_WARN("initialpose in frame '%s', expected '%s': ignored",
                   msg->header.frame_id.c_str(), node_params_.map_frame.c_str());
      return;
    }
    const Eigen::Isometry3d pose = fromPoseMsg(msg->pose.pose);
    std::lock_guard<std::mutex> lock(mutex_);
    // rviz gives x, y and yaw on the ground plane: the height comes from the map.
    pending_initial_ = mapPoseFromXyYaw(*map_, pose.translation().x(), pose.translation().y(),
                                        yawOf(pose.linear()));
    NODELET_INFO("localization: initial pose from %s: %.2f %.2f %.3f (applied with the next scan)",
                 msg->header.frame_id.c_str(), pose.translation().x(), pose.translation().y(),
                 yawOf(pose.linear()));
  }

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    if (stopped_) return;
    if (!localizer_) {
      NODELET_ERROR_THROTTLE(node_params_.warn_throttle_period,
                             "localization: no map loaded, scans ignored");
      return;
    }
    PointCloudPtr cloud = std::make_shared<PointCloud>();
    std::string error;
    if (!fromPointCloud2(*msg, *cloud, &error)) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period, "dropping scan: %s", error.c_str());
      return;
    }
    if (!msg->header.frame_id.empty() && msg->header.frame_id != node_params_.base_link_frame)
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "filtered_points in frame '%s', expected '%s'",
                            msg->header.frame_id.c_str(), node_params_.base_link_frame.c_str());
    const double stamp = msg->header.stamp.toSec();
    if (last_scan_stamp_ && stamp <= *last_scan_stamp_) {
      // A bag replayed again, or time went backwards: start over rather than predict backwards.
      NODELET_WARN("localization: scan at %.3f is not after the last one (%.3f): filter reset",
                   stamp, *last_scan_stamp_);
      localizer_->reset();
      odom_to_base_ = Eigen::Isometry3d::Identity();
      last_scan_stamp_.reset();
    }
    std::optional<Eigen::Vector3d> gyro, accel;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (pending_initial_) {
        localizer_->setInitialPose(*pending_initial_, stamp);
        pending_initial_.reset();
      }
      if (pending_gnss_) {
        localizer_->setGnssFix(pending_gnss_->stamp, pending_gnss_->xy, pending_gnss_->std);
        pending_gnss_.reset();
      }
      if (node_params_.use_imu) {
        const double from = last_scan_stamp_.value_or(stamp - 0.1);
        gyro = gyro_.meanBetween(from, stamp, node_params_.imu_max_gap);
        accel = accel_.meanBetween(from, stamp, node_params_.imu_max_gap);
      }
    }
    if (mount_)
      if (const auto mount = mount_->get()) localizer_->setSensorToBase(*mount);
    const auto t0 = std::chrono::steady_clock::now();
    const LocalizationOutput out = localizer_->process(stamp, cloud, gyro, accel);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    last_scan_stamp_ = stamp;
    odom_to_base_ = odom_to_base_ * out.motion;
    const bool localized = out.status == LocalizationStatus::kTracking ||
                           out.status == LocalizationStatus::kPredicted ||
                           out.status == LocalizationStatus::kRelocalized;
    publishStatus(msg->header.stamp, out, localized, ms);
    if (out.diverged && out.diverged_by_gnss)
      NODELET_WARN(
          "localization: diverged at %.3f (%d GNSS fixes in a row more than %.1f m "
          "from the tracked pose), searching",
          stamp, localizer_->params().gnss_check_fixes, localizer_->params().gnss_check_distance);
    else if (out.diverged)
      NODELET_WARN("localization: diverged at %.3f (%d of the last %d matches rejected), searching",
                   stamp, localizer_->params().divergence_scans,
                   localizer_->params().effectiveDivergenceWindow());
    if (out.status == LocalizationStatus::kRelocalized)
      NODELET_INFO("localization: (re-)localised at %.2f %.2f (fitness %.3f)",
                   out.pose.translation().x(), out.pose.translation().y(), out.fitness);
    // Off the map: predicted only; published (the status says so) so that TF stays continuous.
    if (!localized && out.status != LocalizationStatus::kOffMap) return;
    publishOdometry(msg->header.stamp, out);
  }

  void publishOdometry(const ros::Time& stamp, const LocalizationOutput& out) {
    boost::shared_ptr<nav_msgs::Odometry> odom(new nav_msgs::Odometry);
    odom->header.stamp = stamp;
    odom->header.frame_id = node_params_.map_frame;
    odom->child_frame_id = node_params_.base_link_frame;
    odom->pose.pose = toPoseMsg(out.pose);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) odom->pose.covariance[r * 6 + c] = out.covariance(r, c);
    const PoseUkfState& x = localizer_->filter().state();
    odom->twist.twist.linear.x = x.velocity.x();
    odom->twist.twist.linear.y = x.velocity.y();
    odom->twist.twist.linear.z = x.velocity.z();
    odom->twist.twist.angular.x = x.angular_rate.x();
    odom->twist.twist.angular.y = x.angular_rate.y();
    odom->twist.twist.angular.z = x.angular_rate.z();
    odom_pub_.publish(boost::shared_ptr<const nav_msgs::Odometry>(odom));
    if (!node_params_.publish_tf) return;
    // map -> odom = map -> base_link * (odom -> base_link)^-1: odom -> base_link is the filter's
    // own dead reckoning, or another odometry's (scan_matching) from TF.
    Eigen::Isometry3d odom_to_base = odom_to_base_;
    if (!node_params_.publish_odom_tf) {
      try {
        odom_to_base = fromTransformMsg(tf_buffer_
                                            ->lookupTransform(node_params_.odom_frame,
                                                              node_params_.base_link_frame, stamp,
                                                              ros::Duration(0.1))
                                            .transform);
      } catch (const std::exception& e) {
        NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                              "no %s -> %s at %.3f (%s): map -> odom not sent",
                              node_params_.odom_frame.c_str(), node_params_.base_link_frame.c_str(),
                              stamp.toSec(), e.what());
        return;
      }
    }
    std::vector<geometry_msgs::TransformStamped> tfs(node_params_.publish_odom_tf ? 2 : 1);
    tfs[0].header.stamp = stamp;
    tfs[0].header.frame_id = node_params_.map_frame;
    tfs[0].child_frame_id = node_params_.odom_frame;
    tfs[0].transform = toTransformMsg(out.pose * odom_to_base.inverse());
    if (node_params_.publish_odom_tf) {
      tfs[1].header.stamp = stamp;
      tfs[1].header.frame_id = node_params_.odom_frame;
      tfs[1].child_frame_id = node_params_.base_link_frame;
      tfs[1].transform = toTransformMsg(odom_to_base);
    }
    tf_broadcaster_.sendTransform(tfs);
  }

  void publishStatus(const ros::Time& stamp, const LocalizationOutput& out, bool localized,
                     double ms) {
    boost::shared_ptr<LocalizationReport> msg(new LocalizationReport);
    msg->header.stamp = stamp;
    msg->header.frame_id = node_params_.map_frame;
    msg->state = toString(out.status);
    msg->localized = localized;
    msg->fitness = out.fitness;
    msg->distance_to_map = out.distance_to_map;
    msg->diverged = out.diverged;
    msg->pose.pose = toPoseMsg(out.pose);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) msg->pose.covariance[r * 6 + c] = out.covariance(r, c);
    const LocalizationStats& s = localizer_->stats();
    msg->relocalizations = static_cast<uint32_t>(s.relocalizations);
    msg->divergences = static_cast<uint32_t>(s.divergences);
    msg->time_ms = ms;
    status_pub_.publish(boost::shared_ptr<const LocalizationReport>(msg));
  }

  LocalizationNodeletParams node_params_;  ///< frames, rates, TF (nodelet_params.h)
  std::shared_ptr<const MapPackage> map_;
  std::unique_ptr<Localizer> localizer_;
  std::optional<Eigen::Isometry3d> pending_initial_;
  std::optional<double> last_scan_stamp_;
  Eigen::Isometry3d odom_to_base_ = Eigen::Isometry3d::Identity();
  /// The IMU buffers, pending_initial_ and pending_gnss_ (callbacks run on several threads).
  std::mutex mutex_;
  ImuReadingBuffer gyro_{5.0}, accel_{5.0};  ///< the last 5 s
  std::optional<GnssFix> pending_gnss_;      ///< the newest fix, handed over with the next scan
  std::optional<EnuConverter> map_enu_;      ///< the map package's ENU origin
  ros::Publisher status_pub_, odom_pub_, map_pub_;
  ros::Subscriber cloud_sub_, imu_sub_, initial_sub_, gnss_sub_, mapping_sub_;
  std::atomic<bool> stopped_{false};  ///< slam/mapping said the SLAM back-end maps
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<SensorMountLookup> mount_;  ///< only when deskewing
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::LocalizationNodelet, nodelet::Nodelet)
