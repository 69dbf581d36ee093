// GraphBackendNodelet: keyframes, wall segments, OSM buildings and loop closures -> GraphBackend
// (slam/), optimised on its own thread every optimization_period (or optimize_every_keyframes);
// publishes the corrected pose, path, buildings, markers, map cloud, the occupancy grid and TF
// map -> odom; services save_map and dump_graph. With ~resume_map the saved map's graph is loaded
// first and this drive is a new session of it (slam/map_resume.h), placed on the optimisation
// thread; with ~handover as well, its keyframes are held while the localization nodelet tracks on
// the saved map (localization/status) and mapped once it has left it (slam/localization_handover.h;
// slam/mapping, latched, says which, and map -> odom is published only while mapping).
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Bool.h>
#include <std_msgs/String.h>
#include <tf2_ros/transform_broadcaster.h>
#include <pluginlib/class_list_macros.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "osm_graph_slam/DumpGraph.h"
#include "osm_graph_slam/FloorCoeffs.h"
#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/LineSegmentArray.h"
#include "osm_graph_slam/LocalizationReport.h"
#include "osm_graph_slam/LoopClosure.h"
#include "osm_graph_slam/SaveMap.h"
#include "osm_graph_slam/common/upper_triangle.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/loop/params_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/ros/backend_markers.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/keyframe_conversions.h"
#include "osm_graph_slam/ros/nodelet_logging.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/osm_conversions.h"
#include "osm_graph_slam/ros/ros_param_reader.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/grid_map.h"
#include "osm_graph_slam/slam/keyframe_input.h"
#include "osm_graph_slam/slam/localization_handover.h"
#include "osm_graph_slam/slam/map_export.h"
#include "osm_graph_slam/slam/map_resume.h"
#include "osm_graph_slam/slam/optimization_schedule.h"
#include "osm_graph_slam/slam/params_io.h"

namespace osm_graph_slam {

class GraphBackendNodelet : public nodelet::Nodelet {
 public:
  ~GraphBackendNodelet() override {
    if (input_spinner_) input_spinner_->stop();  // no input callback runs from here on
    {
      std::lock_guard<std::mutex> lock(wake_mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    readParams(RosParamReader(pnh), node_params_);  // defaults: nodelet_params.h

    GraphBackendParams params;
    std::string error;
    if (!readParams(RosParamReader(pnh), params, &error))
      NODELET_ERROR("graph_backend: %s; keeping its default", error.c_str());
    aiding_ = std::make_unique<KeyframeAiding>(
        params.inputs,
        params.initial_yaw_known ? std::optional<double>(params.initial_yaw) : std::nullopt,
        /*heading_from_imu=*/true, /*keep_fixes=*/params.gnss.gnss_prior_std > 0.0);
    auto logger = std::make_shared<Logger>(nodeletLogSink(getName()));
    backend_ = std::make_unique<GraphBackend>(params, logger);
    if (!node_params_.resume_map.empty()) resumeOn(node_params_.resume_map, logger);
    if (node_params_.handover) startHandover(nh);

    pose_pub_ = nh.advertise<geometry_msgs::PoseStamped>("slam/pose", 10);
    path_pub_ = nh.advertise<nav_msgs::Path>("slam/path", 1, true);
    buildings_pub_ = nh.advertise<BuildingArray>("slam/buildings", 1, true);
    markers_pub_ = nh.advertise<visualization_msgs::MarkerArray>("slam/markers", 1, true);
    map_pub_ = nh.advertise<sensor_msgs::PointCloud2>("slam/map_points", 1, true);
    startGridMap(nh, params.grid);
    subscribeInputs(nh, params.inputs.use_imu);
    save_srv_ = pnh.advertiseService("save_map", &GraphBackendNodelet::onSaveMap, this);
    dump_srv_ = pnh.advertiseService("dump_graph", &GraphBackendNodelet::onDumpGraph, this);
    worker_ = std::thread(&GraphBackendNodelet::optimizationLoop, this);
    NODELET_INFO("graph back-end: OSM %s (mode %s), optimisation every %s, frames %s -> %s -> %s",
                 params.use_osm ? "on" : "off", toString(params.mode), scheduleText().c_str(),
                 node_params_.map_frame.c_str(), node_params_.odom_frame.c_str(),
                 node_params_.base_link_frame.c_str());
  }

  /// The saved map's graph goes in first; its origin is the map's. A map that cannot be loaded is
  /// an error said once, and this drive is mapped on its own.
  void resumeOn(const std::string& directory, const std::shared_ptr<const Logger>& logger) {
    std::string error;
    // The localiser and loop detector of the placement and the inter-session loops are set up
    // as the launch file set up those nodelets.
    LocalizationParams localization;
    readParams(RosParamReader(ros::NodeHandle(node_params_.localization_ns)), localization);
    LoopDetectorParams loops;
    readParams(RosParamReader(ros::NodeHandle(node_params_.loop_detection_ns)), loops);
    resume_ = MapResume::load(directory, MapResumeParams(), localization, loops, *backend_, logger,
                              &error);
    if (!resume_) {
      NODELET_ERROR("graph_backend: %s; mapping without it", error.c_str());
      return;
    }
    if (const auto origin = backend_->origin()) {
      origin_ = *origin;
      aiding_->sensors().setOrigin(origin->originLat(), origin->originLon(), origin->originAlt());
    }
    NODELET_INFO(
        "graph_backend: resuming on %s (%zu keyframes of %zu session(s)); this drive is "
        "session %u",
        directory.c_str(), resume_->status().saved_keyframes, resume_->status().saved_sessions,
        resume_->session());
    resume_pub_ = getNodeHandle().advertise<std_msgs::String>("slam/resume_status", 1, true);
    publishResumeStatus();
  }

  /// Mapping waits for the localiser to leave the saved map. Without a saved map there is nothing
  /// to localise on: an error said once, and this drive is mapped from the start.
  void startHandover(ros::NodeHandle& nh) {
    if (!resume_) {
      NODELET_ERROR(
          "graph_backend: handover needs a saved map (resume_map); mapping from the start");
      return;
    }
    LocalizationHandoverParams params;
    params.leave_after = node_params_.handover_leave_after;
    params.ties = node_params_.handover_ties;
    handover_ = std::make_unique<LocalizationHandover>(params);
    mapping_ = false;
    mapping_pub_ = nh.advertise<std_msgs::Bool>("slam/mapping", 1, true);
    std_msgs::Bool msg;
    msg.data = false;
    mapping_pub_.publish(msg);
    NODELET_INFO(
        "graph_backend: localising on the saved map (localization/status); mapping starts once "
        "the localiser has not tracked for %.1f s",
        params.leave_after);
  }

  /// slam/resume_status (latched): the session's state, whenever it changes.
  void publishResumeStatus() {
    std_msgs::String msg;
    msg.data = resume_->status().text();
    if (msg.data == last_resume_status_) return;
    last_resume_status_ = msg.data;
    resume_pub_.publish(msg);
  }

  /// Live keyframe ids of a resumed map are the live session's in the graph.
  uint64_t graphId(uint64_t id) const { return resume_ ? resume_->graphId(id) : id; }

  /// Optimisation thread: the queued live keyframes are placed or searched against the saved
  /// map (global localisation and loop registration take too long for the input thread).
  void resumeKeyframes() {
    std::deque<HandoverKeyframe> queued;
    {
      std::lock_guard<std::mutex> guard(resume_mutex_);
      queued.swap(resume_queue_);
    }
    const bool was_placed = resume_->status().placed;
    for (const auto& h : queued)
      for (const auto& loop : resume_->process(h.keyframe, *backend_, h.localized))
        backend_->addLoopClosure(loop);
    if (!was_placed && resume_->status().placed)
      NODELET_INFO("graph_backend: %s", resume_->status().text().c_str());
    publishResumeStatus();
  }

  /// A grid with bad parameters is an error said once; the rest of the back-end runs without it.
  void startGridMap(ros::NodeHandle& nh, const OccupancyGridParams& params) {
    if (!params.enabled) return;
    const std::string error = occupancyGridParamsError(params);
    if (!error.empty()) {
      NODELET_ERROR("graph_backend: %s; slam/grid_map is off", error.c_str());
      return;
    }
    grid_ = std::make_unique<OccupancyGrid>(params);
    grid_pub_ = nh.advertise<nav_msgs::OccupancyGrid>("slam/grid_map", 1, true);
  }

  std::string scheduleText() const {
    char text[96];
    if (keyframeDriven())
      std::snprintf(text, sizeof(text), "%d keyframes (and after %.1f s without one)",
                    node_params_.optimize_every_keyframes, node_params_.optimization_period);
    else
      std::snprintf(text, sizeof(text), "%.1f s", node_params_.optimization_period);
    return text;
  }

  /// Inputs and TF on a queue and thread of their own. On the manager's shared worker threads a
  /// saturated manager starved the keyframe subscription until its queue overflowed: a 35-minute
  /// soak lost 22 % of the keyframes silently (doc/reliability.md). The callbacks below only
  /// convert and queue, so one thread keeps up; the back-end's own queue is unbounded.
  void subscribeInputs(const ros::NodeHandle& shared_nh, bool use_imu) {
    ros::NodeHandle nh(shared_nh);
    nh.setCallbackQueue(&input_queue_);
    const uint32_t q = static_cast<uint32_t>(std::max(1, node_params_.input_queue_size));
    keyframe_sub_ = nh.subscribe("keyframe", q, &GraphBackendNodelet::onKeyframe, this);
    segments_sub_ = nh.subscribe("line_segments", q, &GraphBackendNodelet::onSegments, this);
    buildings_sub_ = nh.subscribe("osm/buildings", 10, &GraphBackendNodelet::onBuildings, this);
    loops_sub_ = nh.subscribe("loop_closures", q, &GraphBackendNodelet::onLoop, this);
    floor_sub_ = nh.subscribe("floor_coeffs", q, &GraphBackendNodelet::onFloor, this);
    origin_sub_ = nh.subscribe("osm/origin", 1, &GraphBackendNodelet::onOrigin, this);
    if (use_imu) imu_sub_ = nh.subscribe("imu/data", 200, &GraphBackendNodelet::onImu, this);
    fix_sub_ = nh.subscribe("gps/fix", 50, &GraphBackendNodelet::onFix, this);
    if (handover_)
      localization_sub_ =
          nh.subscribe("localization/status", 100, &GraphBackendNodelet::onLocalization, this);
    if (node_params_.tf_publish_rate > 0.0)
      tf_timer_ = nh.createWallTimer(ros::WallDuration(1.0 / node_params_.tf_publish_rate),
                                     &GraphBackendNodelet::publishTf, this);
    input_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &input_queue_);
    input_spinner_->start();
  }

  // --- inputs (input thread: convert and queue only, never wait for the optimisation) ----------
  void onKeyframe(const KeyFrameConstPtr& msg) {
    KeyframeInput kf;
    std::string error;
    if (!fromKeyFrameMsg(*msg, kf, &error))
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "keyframe %lu without a usable cloud (%s); kept for the graph",
                            static_cast<unsigned long>(msg->id), error.c_str());
    addSensorInputs(kf);
    {
      std::lock_guard<std::mutex> guard(stamp_mutex_);
      last_stamp_ = msg->header.stamp;
      keyframe_stamps_[graphId(kf.id)] = msg->header.stamp;
    }
    if (!handover_) return addToGraph({std::move(kf), std::nullopt});
    handover_->addKeyframe(kf);
    mapReleasedKeyframes();
  }

  /// A hand-over: the localiser's result for one scan, which may release held keyframes.
  void onLocalization(const LocalizationReportConstPtr& msg) {
    if (mapping_) return;
    const bool tracking = msg->state == "tracking" || msg->state == "relocalized";
    handover_->addLocalization(msg->header.stamp.toSec(), tracking, fromPoseMsg(msg->pose.pose));
    mapReleasedKeyframes();
  }

  void mapReleasedKeyframes() {
    for (auto& released : handover_->release()) addToGraph(std::move(released));
    if (!mapping_) dropLocalizedInputs();
  }

  /// The first keyframe mapped after a hand-over: map -> odom is where the localiser put it
  /// until the first optimisation, and the localization nodelet hands TF over.
  void startMapping(const HandoverKeyframe& first) {
    mapping_ = true;
    if (first.localized) {
      std::lock_guard<std::mutex> guard(map_to_odom_mutex_);
      map_to_odom_ = *first.localized * first.keyframe.odom_pose.inverse();
    }
    std_msgs::Bool msg;
    msg.data = true;
    mapping_pub_.publish(msg);
    NODELET_INFO(
        "graph_backend: the localiser has left the saved map (%.3f s): mapping from keyframe %lu "
        "on, %s; %zu keyframes were localised, not mapped",
        *handover_->handoverStamp(), static_cast<unsigned long>(first.keyframe.id),
        first.localized ? "placed by the localiser" : "unplaced (the localiser never tracked)",
        handover_->keyframesLocalized());
    dropLocalizedInputs();
  }

  void addToGraph(HandoverKeyframe h) {
    if (handover_ && !mapping_) startMapping(h);
    const uint64_t live_id = h.keyframe.id;
    if (resume_) resume_->renumber(h.keyframe);  // the live session's id from here on
    const uint64_t graph_id = h.keyframe.id;
    const Eigen::Isometry3d odom_pose = h.keyframe.odom_pose;
    const ros::Time stamp = keyframeStamp(graph_id, ros::Time().fromSec(h.keyframe.stamp));
    backend_->addKeyframe(h.keyframe);
    if (resume_) {
      std::lock_guard<std::mutex> guard(resume_mutex_);
      resume_queue_.push_back(std::move(h));
    }
    forwardHeldInputs(live_id, graph_id);
    keyframeReceived();
    // A pose right away (map->odom of the last optimisation): the OSM buffer follows it.
    geometry_msgs::PoseStamped pose;
    pose.header.stamp = stamp;
    pose.header.frame_id = node_params_.map_frame;
    pose.pose = toPoseMsg(cachedMapToOdom() * odom_pose);
    pose_pub_.publish(pose);
  }

  /// Inputs of a keyframe a hand-over still holds wait with it; those of a keyframe it
  /// localised and never maps are dropped. True: the input goes into the graph now.
  template <typename Held, typename Input>
  bool passOrHold(uint64_t live_id, std::map<uint64_t, Held>& held, Input&& input) {
    if (!handover_) return true;
    switch (handover_->fate(live_id)) {
      case LocalizationHandover::Fate::kMapped:
        return true;
      case LocalizationHandover::Fate::kWaiting:
        held[live_id] = std::forward<Input>(input);
        return false;
      case LocalizationHandover::Fate::kLocalized:
        return false;
    }
    return false;
  }

  void forwardHeldInputs(uint64_t live_id, uint64_t graph_id) {
    if (!handover_) return;
    if (auto it = held_segments_.find(live_id); it != held_segments_.end()) {
      backend_->addLineSegments(graph_id, std::move(it->second));
      held_segments_.erase(it);
    }
    if (auto it = held_floors_.find(live_id); it != held_floors_.end()) {
      backend_->addFloor(graph_id, it->second);
      held_floors_.erase(it);
    }
  }

  void dropLocalizedInputs() {
    const auto localized = [this](uint64_t id) {
      return handover_->fate(id) == LocalizationHandover::Fate::kLocalized;
    };
    while (!held_segments_.empty() && localized(held_segments_.begin()->first))
      held_segments_.erase(held_segments_.begin());
    while (!held_floors_.empty() && localized(held_floors_.begin()->first))
      held_floors_.erase(held_floors_.begin());
  }

  void onFloor(const FloorCoeffsConstPtr& msg) {
    if (!msg->found) return;  // floor_detection logs a floor lost for long
    const Eigen::Vector4d coeffs(msg->coeffs[0], msg->coeffs[1], msg->coeffs[2], msg->coeffs[3]);
    if (!coeffs.allFinite() || coeffs.head<3>().norm() < 1e-6) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "floor of keyframe %lu is not a plane; ignored",
                            static_cast<unsigned long>(msg->keyframe_id));
      return;
    }
    if (passOrHold(msg->keyframe_id, held_floors_, coeffs))
      backend_->addFloor(graphId(msg->keyframe_id), coeffs);
  }

  /// The keyframe's exact header stamp (the core keeps seconds as a double, which loses the
  /// nanoseconds at epoch times: TF lookups at path stamps would then miss by ~50 ns).
  ros::Time keyframeStamp(const KeyframeState& kf) {
    return keyframeStamp(kf.id, ros::Time().fromSec(kf.stamp));
  }
  /// The header stamp the keyframe `graph_id` came with, else `fallback`.
  ros::Time keyframeStamp(uint64_t graph_id, const ros::Time& fallback) {
    std::lock_guard<std::mutex> guard(stamp_mutex_);
    const auto it = keyframe_stamps_.find(graph_id);
    return it != keyframe_stamps_.end() ? it->second : fallback;
  }

  ros::Time lastStamp() {
    std::lock_guard<std::mutex> guard(stamp_mutex_);
    return last_stamp_;
  }

  /// The keyframe's IMU attitude, INS yaw and GNSS position (matched by time); the first
  /// keyframe's heading, when the IMU decides it, goes to the back-end, and the map -> odom
  /// published until the first optimisation follows it.
  void addSensorInputs(KeyframeInput& kf) {
    const std::optional<FirstHeading> first = aiding_->aid(aiding_->at(kf.stamp), kf);
    if (!first) return;
    if (!first->warning.empty()) NODELET_WARN("%s", first->warning.c_str());
    if (first->from_imu && first->yaw) {
      // A resumed map keeps its own heading: the IMU's is this drive's session start.
      if (resume_)
        backend_->setSessionHeading(resume_->session(), *first->yaw);
      else
        backend_->setInitialHeading(*first->yaw);
      NODELET_INFO("initial heading %.1f deg from imu/data", *first->yaw * 180.0 / M_PI);
    }
    first_keyframe_seen_ = true;
    std::lock_guard<std::mutex> guard(map_to_odom_mutex_);
    map_to_odom_ = initialMapToOdom(kf.odom_pose, first->yaw,
                                    kf.gnss_position.value_or(Eigen::Vector2d::Zero()));
  }

  void onImu(const sensor_msgs::ImuConstPtr& msg) {
    if (msg->orientation_covariance[0] < 0.0) return;  // REP-145: no orientation
    const auto& q = msg->orientation;
    aiding_->sensors().addOrientation(msg->header.stamp.toSec(),
                                      Eigen::Quaterniond(q.w, q.x, q.y, q.z));
  }

  void onFix(const sensor_msgs::NavSatFixConstPtr& msg) {
    if (msg->status.status < sensor_msgs::NavSatStatus::STATUS_FIX) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "gps/fix at %.3f has no fix (status %d); ignored",
                            msg->header.stamp.toSec(), msg->status.status);
      return;
    }
    // NaN altitude: unknown (then the fix holds x and y only).
    if (!aiding_->sensors().addFix({msg->header.stamp.toSec(), msg->latitude, msg->longitude,
                                    msg->altitude, navSatFixStd(*msg)}))
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "gps/fix at %.3f has a non-finite position (%f, %f); ignored",
                            msg->header.stamp.toSec(), msg->latitude, msg->longitude);
  }

  void onSegments(const LineSegmentArrayConstPtr& msg) {
    std::vector<LineSegment2> segments;
    segments.reserve(msg->segments.size());
    for (const auto& s : msg->segments) {
      if (!std::isfinite(s.start.x) || !std::isfinite(s.start.y) || !std::isfinite(s.end.x) ||
          !std::isfinite(s.end.y))
        continue;
      segments.emplace_back(Eigen::Vector2d(s.start.x, s.start.y),
                            Eigen::Vector2d(s.end.x, s.end.y), s.support);
    }
    if (passOrHold(msg->keyframe_id, held_segments_, std::move(segments)))
      backend_->addLineSegments(graphId(msg->keyframe_id), std::move(segments));
  }

  void onBuildings(const BuildingArrayConstPtr& msg) {
    if (!msg->header.frame_id.empty() && msg->header.frame_id != node_params_.map_frame) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "osm/buildings in frame '%s', expected '%s'; ignored",
                            msg->header.frame_id.c_str(), node_params_.map_frame.c_str());
      return;
    }
    // The message carries ENU outlines only: the prior's lat/lon (dump_graph's
    // buildings_prior.geojson, which evaluate_map and replay_backend read) come from the origin
    // (the nodelet's copy: asking the back-end would wait for a running optimisation).
    backend_->addBuildings(buildingsFromMsg(*msg, origin_ ? &*origin_ : nullptr),
                           Eigen::Vector2d(msg->query_center.x, msg->query_center.y),
                           msg->query_radius);
  }

  void onLoop(const LoopClosureConstPtr& msg) {
    LoopClosureInput loop;
    loop.from_id = graphId(msg->from_id);
    loop.to_id = graphId(msg->to_id);
    loop.relative_pose = fromPoseMsg(msg->relative_pose);
    for (int i = 0; i < 36; ++i) loop.information(i / 6, i % 6) = msg->information[i];
    if (!loop.information.allFinite() || loop.information.diagonal().minCoeff() <= 0.0) {
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "loop %lu -> %lu has an invalid information matrix; ignored",
                            static_cast<unsigned long>(msg->from_id),
                            static_cast<unsigned long>(msg->to_id));
      return;
    }
    // A loop that names a keyframe a hand-over localised (or still holds) has no vertex.
    if (handover_ && (handover_->fate(msg->from_id) != LocalizationHandover::Fate::kMapped ||
                      handover_->fate(msg->to_id) != LocalizationHandover::Fate::kMapped)) {
      NODELET_INFO_ONCE(
          "graph_backend: loops between keyframes localised on the saved map are not mapped; "
          "dropped (their keyframes are the saved map's)");
      return;
    }
    backend_->addLoopClosure(loop);
  }

  void onOrigin(const sensor_msgs::NavSatFixConstPtr& fix) {
    if (!std::isfinite(fix->latitude) || !std::isfinite(fix->longitude)) return;
    if (origin_) return;
    const double altitude = std::isfinite(fix->altitude) ? fix->altitude : 0.0;
    origin_.emplace(fix->latitude, fix->longitude, altitude);
    backend_->setOrigin(fix->latitude, fix->longitude, altitude);
    aiding_->sensors().setOrigin(fix->latitude, fix->longitude, fix->altitude);
    NODELET_INFO("map origin (ENU) at %.7f, %.7f", fix->latitude, fix->longitude);
  }

  // --- optimisation thread ----------------------------------------------------------------------
  bool keyframeDriven() const { return node_params_.optimize_every_keyframes > 0; }

  /// Input thread: counts the keyframe and, on the keyframe-driven schedule, wakes the
  /// optimisation thread once enough arrived.
  void keyframeReceived() {
    std::lock_guard<std::mutex> lock(wake_mutex_);
    ++keyframes_received_;
    last_keyframe_wall_ = std::chrono::steady_clock::now();
    if (keyframeDriven() && keyframeUpdateDue(keyframes_received_, keyframes_at_update_,
                                              node_params_.optimize_every_keyframes, 0.0, 1.0))
      wake_.notify_one();
  }

  /// Whether the wake-up that just happened runs an update (wake_mutex_ held).
  bool updateDue() const {
    if (!keyframeDriven()) return true;
    const double idle_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - last_keyframe_wall_)
            .count();
    return keyframeUpdateDue(keyframes_received_, keyframes_at_update_,
                             node_params_.optimize_every_keyframes, idle_s,
                             node_params_.optimization_period);
  }

  void optimizationLoop() {
    std::unique_lock<std::mutex> lock(wake_mutex_);
    double wait_s = node_params_.optimization_period;
    while (!stop_) {
      wake_.wait_for(lock, std::chrono::duration<double>(wait_s));
      if (stop_) break;
      if (!updateDue()) continue;
      keyframes_at_update_ = keyframes_received_;
      lock.unlock();
      std::unique_lock<std::mutex> graph_lock(graph_mutex_);
      if (resume_) resumeKeyframes();
      const BackendUpdateReport report = backend_->update();
      wait_s = keyframeDriven()
                   ? node_params_.optimization_period
                   : optimizationWait(node_params_.optimization_period, report.total_ms / 1000.0,
                                      node_params_.optimization_max_duty_cycle);
      reportBacklog(report, wait_s);
      if (report.optimized) {
        {
          std::lock_guard<std::mutex> guard(map_to_odom_mutex_);
          map_to_odom_ = backend_->mapToOdom();
          ++map_to_odom_version_;
        }
        NODELET_DEBUG(
            "graph: +%zu keyframes, +%zu loops, +%zu map priors, +%zu building edges, "
            "%zu overlap edges, %zu shared walls, chi2 %.3g -> %.3g, %.1f ms",
            report.keyframes_added, report.loops_added, report.global_priors, report.building_edges,
            report.overlap_edges, report.shared_walls, report.phase1.initial_chi2,
            report.phase1.final_chi2, report.total_ms);
        publishOutputs();
      }
      graph_lock.unlock();
      lock.lock();
    }
  }

  /// Lost keyframes and updates slower than the period are worth a warning (throttled); the
  /// back-end logs the first gap once with its reason, save_map and dump_graph count them.
  void reportBacklog(const BackendUpdateReport& report, double next_wait_s) {
    if (report.keyframes_missing > 0)
      NODELET_WARN_THROTTLE(node_params_.warn_throttle_period,
                            "%zu keyframes missing so far (never received by the back-end)",
                            backend_->missingKeyframes());
    if (report.full_batch_for_loop)
      NODELET_INFO_THROTTLE(10.0,
                            "a new loop to a keyframe outside the optimisation window still "
                            "disagreed: full batch over %zu keyframes (%.1f s)",
                            backend_->numKeyframes(), report.total_ms / 1000.0);
    // Once a minute: a large graph is slow at every update (soak: 3.1-3.7 s at 3,100 keyframes).
    if (report.total_ms > 1000.0 * node_params_.optimization_period)
      NODELET_WARN_THROTTLE(
          60.0,
          "graph update took %.1f s (optimization_period %.1f s, %s) with %zu keyframes: phase 1 "
          "%.0f ms (%d iterations), phase 2 %.0f ms, joint %.0f ms; next in %.1f s "
          "(optimization_max_duty_cycle %.2f), inputs wait in the queue",
          report.total_ms / 1000.0, node_params_.optimization_period,
          report.window_start ? "windowed" : "full batch", backend_->numKeyframes(),
          report.phase1.time_ms, report.phase1.iterations, report.phase2.time_ms,
          report.joint.time_ms, next_wait_s, node_params_.optimization_max_duty_cycle);
  }

  Eigen::Isometry3d cachedMapToOdom() {
    std::lock_guard<std::mutex> guard(map_to_odom_mutex_);
    return map_to_odom_;
  }

  void publishOutputs() {
    std_msgs::Header header;
    header.frame_id = node_params_.map_frame;
    header.stamp = lastStamp();
    const std::vector<KeyframeState> keyframes = backend_->keyframes();
    nav_msgs::PathPtr path(new nav_msgs::Path);
    path->header = header;
    for (const auto& kf : keyframes) {
      geometry_msgs::PoseStamped p;
      p.header.frame_id = node_params_.map_frame;
      p.header.stamp = keyframeStamp(kf);
      p.pose = toPoseMsg(kf.map_pose);
      path->poses.push_back(p);
    }
    path_pub_.publish(path);
    if (!keyframes.empty()) {
      geometry_msgs::PoseStamped pose = path->poses.back();
      pose_pub_.publish(pose);
    }
    const std::vector<Building> buildings = backend_->correctedBuildings();
    buildings_pub_.publish(buildingArrayToMsg(buildings, header, Eigen::Vector2d::Zero(), 0.0));
    if (markers_pub_.getNumSubscribers() > 0)
      markers_pub_.publish(
          backendMarkers(backend_->graphSnapshot(), keyframes, backend_->buildings(), header));
    publishGridMap(keyframes, header);
    if (map_pub_.getNumSubscribers() > 0) {  // built only while someone listens
      sensor_msgs::PointCloud2Ptr cloud(new sensor_msgs::PointCloud2);
      toPointCloud2(*buildMapCloud(keyframes, node_params_.map_cloud_resolution), *cloud);
      cloud->header = header;
      map_pub_.publish(cloud);
    }
  }

  /// Kept in step with the graph after every optimisation (new keyframes inserted, moved ones
  /// re-rendered) even without subscribers: the latched message and save_map need it whole.
  void publishGridMap(const std::vector<KeyframeState>& keyframes, const std_msgs::Header& header) {
    if (!grid_) return;
    const GridMapUpdate update = updateGridMap(*grid_, keyframes);
    if (update.inserted == 0 && update.moved == 0) return;
    nav_msgs::OccupancyGridPtr msg(new nav_msgs::OccupancyGrid);
    toOccupancyGridMsg(grid_->image(), header, *msg);
    grid_pub_.publish(msg);
    NODELET_DEBUG("grid: +%zu keyframes, %zu re-rendered (%.1f ms)", update.inserted, update.moved,
                  update.move_ms);
  }

  void publishTf(const ros::WallTimerEvent&) {
    // Not backend_->numKeyframes(): it waits for a running optimisation, and at 20 Hz that wait
    // held a worker thread of the manager for the whole optimisation (the soak's starvation).
    if (!first_keyframe_seen_ || !mapping_) return;  // a hand-over: the localiser publishes it
    // Stamped with the current time, as map -> odom corrects odometry from now on; the latest
    // keyframe's stamp republished at 20 Hz made tf2 warn TF_REPEATED_DATA thousands of times.
    // A clock standing still (paused or finished bag) publishes nothing new, unless an
    // optimisation changed the correction since: that one goes out 1 us after the previous
    // broadcast (tf2 drops a repeated stamp), so TF shows the final map, not the one before.
    Eigen::Isometry3d map_to_odom;
    uint64_t version = 0;
    {
      std::lock_guard<std::mutex> guard(map_to_odom_mutex_);
      map_to_odom = map_to_odom_;
      version = map_to_odom_version_;
    }
    const ros::Time now = ros::Time::now();
    ros::Time stamp = now.isZero() ? lastStamp() : now;
    if (!last_tf_stamp_.isZero() && stamp + ros::Duration(kClockJumpBack) < last_tf_stamp_) {
      // The clock jumped back (a looped bag): TF listeners cleared their buffers, so map -> odom
      // must go out at the new times, not only once the clock passes the old ones.
      NODELET_WARN("clock jumped back %.1f s: map -> odom restamped from now on",
                   (last_tf_stamp_ - stamp).toSec());
      last_tf_stamp_ = ros::Time();
    }
    if (stamp <= last_tf_stamp_) {
      if (version == tf_version_) return;
      stamp = last_tf_stamp_ + ros::Duration(0, 1000);
    }
    last_tf_stamp_ = stamp;
    tf_version_ = version;
    geometry_msgs::TransformStamped tf;
    tf.header.stamp = stamp;
    tf.header.frame_id = node_params_.map_frame;
    tf.child_frame_id = node_params_.odom_frame;
    tf.transform = toTransformMsg(map_to_odom);
    tf_broadcaster_.sendTransform(tf);
  }

  // --- services ---------------------------------------------------------------------------------
  bool onSaveMap(SaveMap::Request& req, SaveMap::Response& res) {
    std::lock_guard<std::mutex> graph_lock(graph_mutex_);
    if (resume_) resumeKeyframes();
    backend_->update();  // include everything received so far
    // The saved map.pgm is the grid slam/grid_map shows, both brought up to this update.
    std_msgs::Header header;
    header.frame_id = node_params_.map_frame;
    header.stamp = lastStamp();
    publishGridMap(backend_->keyframes(), header);
    const MapExportResult r =
        saveMap(*backend_, req.destination, req.resolution, nullptr, grid_.get());
    res.success = r.success;
    res.message = r.message;
    if (resume_) res.message += "; " + resume_->status().text();
    if (handover_ && !mapping_) res.message += "; localising on the saved map, nothing mapped yet";
    res.files = r.files;
    if (r.success)
      NODELET_INFO("save_map: %s", res.message.c_str());
    else
      NODELET_WARN("save_map failed: %s", r.message.c_str());
    return true;
  }

  bool onDumpGraph(DumpGraph::Request& req, DumpGraph::Response& res) {
    std::lock_guard<std::mutex> graph_lock(graph_mutex_);
    const MapExportResult r = dumpGraph(*backend_, req.destination);
    res.success = r.success;
    res.message = r.message;
    res.files = r.files;
    if (!r.success) NODELET_WARN("dump_graph failed: %s", r.message.c_str());
    return true;
  }

  /// [s] the clock going back more than this is a jump (a looped bag), not jitter.
  static constexpr double kClockJumpBack = 1.0;
  GraphBackendNodeletParams node_params_;  ///< frames, rates, TF (nodelet_params.h)
  std::unique_ptr<GraphBackend> backend_;
  std::mutex map_to_odom_mutex_;
  Eigen::Isometry3d map_to_odom_ = Eigen::Isometry3d::Identity();
  std::mutex stamp_mutex_;
  ros::Time last_stamp_;
  std::map<uint64_t, ros::Time> keyframe_stamps_;

  uint64_t map_to_odom_version_ = 0;
  /// One optimisation or one save at a time: the files of a save come from one state of the graph
  /// (the backend locks each accessor, not the sequence of them a save makes).
  std::mutex graph_mutex_;   ///< counts optimisations that set map_to_odom_
  ros::Time last_tf_stamp_;  ///< stamp of the last map -> odom broadcast
  uint64_t tf_version_ = 0;  ///< map_to_odom_version_ of that broadcast
  std::thread worker_;
  std::mutex wake_mutex_;  ///< guards stop_ and the keyframe counts below
  std::condition_variable wake_;
  bool stop_ = false;
  uint64_t keyframes_received_ = 0;
  uint64_t keyframes_at_update_ = 0;  ///< keyframes_received_ when the last update started
  std::chrono::steady_clock::time_point last_keyframe_wall_;

  tf2_ros::TransformBroadcaster tf_broadcaster_;
  ros::Publisher pose_pub_, path_pub_, buildings_pub_, markers_pub_, map_pub_, grid_pub_;
  /// Null when grid_enabled is false or its keys are bad.
  std::unique_ptr<OccupancyGrid> grid_;
  std::unique_ptr<KeyframeAiding> aiding_;  ///< imu/data and gps/fix by time, the first heading
  std::atomic<bool> first_keyframe_seen_{false};
  /// Subscriptions and the TF timer (subscribeInputs); outlives them (they unregister from it).
  ros::CallbackQueue input_queue_;
  ros::Subscriber imu_sub_, fix_sub_;
  ros::Subscriber keyframe_sub_, segments_sub_, buildings_sub_, loops_sub_, origin_sub_, floor_sub_;
  ros::ServiceServer save_srv_, dump_srv_;
  ros::WallTimer tf_timer_;
  std::unique_ptr<ros::AsyncSpinner> input_spinner_;  ///< stopped first (destructor)
  std::optional<EnuConverter> origin_;                ///< the map origin, on the input thread only
  std::unique_ptr<MapResume> resume_;                 ///< with ~resume_map
  std::mutex resume_mutex_;                           ///< guards resume_queue_
  std::deque<HandoverKeyframe> resume_queue_;         ///< live keyframes not yet placed/searched
  /// ~handover (input thread only, as the held inputs).
  std::unique_ptr<LocalizationHandover> handover_;
  std::atomic<bool> mapping_{true};  ///< false while a hand-over localises
  std::map<uint64_t, std::vector<LineSegment2>> held_segments_;  ///< by the tracker's id
  std::map<uint64_t, Eigen::Vector4d> held_floors_;
  ros::Subscriber localization_sub_;
  ros::Publisher mapping_pub_;  ///< slam/mapping
  ros::Publisher resume_pub_;   ///< slam/resume_status
  std::string last_resume_status_;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::GraphBackendNodelet, nodelet::Nodelet)
