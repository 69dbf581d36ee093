// Loop detection nodelet: KeyFrame -> LoopClosure. Thin adapter around LoopDetector.
#include <geometry_msgs/Pose.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <osm_graph_slam/KeyFrame.h>
#include <osm_graph_slam/LoopClosure.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>

#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <thread>

#include "osm_graph_slam/ros/nodelet_logging.h"

#include "osm_graph_slam/common/sequence_gaps.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/loop/params_io.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {
namespace {

geometry_msgs::Pose toMsg(const Eigen::Isometry3d& t) {
  geometry_msgs::Pose pose;
  pose.position.x = t.translation().x();
  pose.position.y = t.translation().y();
  pose.position.z = t.translation().z();
  const Eigen::Quaterniond q(t.linear());
  pose.orientation.w = q.w();
  pose.orientation.x = q.x();
  pose.orientation.y = q.y();
  pose.orientation.z = q.z();
  return pose;
}

}  // namespace

class LoopDetectionNodelet : public nodelet::Nodelet {
 public:
  ~LoopDetectionNodelet() override {
    if (input_spinner_) input_spinner_->stop();  // no input callback runs from here on
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      stop_ = true;
    }
    pending_cv_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    LoopDetectorParams params;
    readParams(RosParamReader(pnh), params);
    LoopDetectionNodeletParams np;  // defaults: nodelet_params.h
    readParams(RosParamReader(pnh), np);
    mode_ = np.mode;
    node_params_ = np;
    search_in_map_ = params.search_frame == "map";
    if (!search_in_map_ && params.search_frame != "odometry") {
      NODELET_ERROR("loop_detection: unknown search_frame '%s' (odometry | map); using odometry",
                    params.search_frame.c_str());
    }
    if (mode_ != "odometry" && mode_ != "place_recognition") {
      NODELET_ERROR(
          "loop_detection: unknown mode '%s' (odometry | place_recognition); using "
          "odometry",
          mode_.c_str());
      mode_ = "odometry";
    }
    LogSink sink = nodeletLogSink(getName());
    try {
      detector_ = std::make_unique<LoopDetector>(params, sink);
    } catch (const std::exception& e) {
      NODELET_ERROR("loop_detection: cannot create the detector: %s", e.what());
      return;
    }
    publisher_ = nh.advertise<osm_graph_slam::LoopClosure>("loop_closures", 16);
    // Keyframes arrive on a queue and thread of their own and are searched on a worker: on the
    // manager's shared threads, behind a slow search, the subscription overflowed (a 60-minute
    // soak never gave 2,563 keyframes to loop_detection; doc/loop.md "The nodelet's threads").
    ros::NodeHandle input_nh(nh);
    input_nh.setCallbackQueue(&input_queue_);
    subscriber_ = input_nh.subscribe("keyframe", std::max(1, np.input_queue_size),
                                     &LoopDetectionNodelet::onKeyframe, this);
    // The back-end's corrected keyframes: the stored ones follow them (LoopDetector::updatePoses)
    // and new ones are moved by the map -> odom they imply (no TF listener of our own: a second
    // one in the manager would log every clock jump twice).
    if (search_in_map_)
      path_subscriber_ = input_nh.subscribe("slam/path", 1, &LoopDetectionNodelet::onPath, this);
    worker_ = std::thread(&LoopDetectionNodelet::searchLoop, this);
    input_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &input_queue_);
    input_spinner_->start();
    NODELET_INFO("loop_detection: mode %s, registration %s, k = %d", mode_.c_str(),
                 params.registration.method.c_str(), params.num_candidates);
  }

  /// Input thread: count gaps and queue; the search runs on the worker.
  void onKeyframe(const osm_graph_slam::KeyFrameConstPtr& msg) {
    if (keyframe_ids_.observe(msg->id) > 0)
      NODELET_WARN_THROTTLE(10.0,
                            "keyframes (%s) never reached loop_detection (%lu so far): "
                            "its queue overflowed; no loop is searched from them",
                            keyframe_ids_.lastGap().c_str(), keyframe_ids_.missing());
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      pending_.push_back(msg);
    }
    pending_cv_.notify_one();
  }

  /// Input thread: only the newest path is kept; the worker applies it before its next search.
  void onPath(const nav_msgs::PathConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      pending_path_ = msg;
    }
    pending_cv_.notify_one();
  }

  /// Worker: the stored keyframes take the back-end's poses, matched by stamp (the path's poses
  /// carry the keyframes' stamps, not their ids); map -> odom is the newest matched keyframe's
  /// map pose times its odometry pose inverted, as the back-end computes it.
  void applyPath(const nav_msgs::Path& path) {
    std::vector<std::pair<uint64_t, Eigen::Isometry3d>> poses;
    poses.reserve(path.poses.size());
    // A looped bag repeats its stamps: the path (in id order) names the keyframes of one stamp
    // in the order they came.
    std::map<ros::Time, size_t> seen;
    for (const auto& p : path.poses) {
      const auto it = received_by_stamp_.find(p.header.stamp);
      if (it == received_by_stamp_.end()) continue;
      const size_t k = seen[p.header.stamp]++;
      if (k >= it->second.size()) continue;
      const Eigen::Isometry3d map_pose = fromPoseMsg(p.pose);
      poses.emplace_back(it->second[k].id, map_pose);
      map_to_odom_ = map_pose * it->second[k].odom_pose.inverse();
    }
    const size_t moved = detector_->updatePoses(poses);
    NODELET_INFO_ONCE(
        "loop_detection: search_frame map: the stored keyframes follow the back-end's slam/path "
        "(first update: %zu of %zu moved)",
        moved, detector_->size());
  }

  /// Worker: every keyframe joins the database; when the search fell behind, only the newest
  /// waiting keyframe is searched from (a loop from a stale keyframe is worth less than keeping
  /// up), and the skipped searches are counted and said.
  void searchLoop() {
    for (;;) {
      std::deque<osm_graph_slam::KeyFrameConstPtr> batch;
      nav_msgs::PathConstPtr path;
      {
        std::unique_lock<std::mutex> lock(pending_mutex_);
        pending_cv_.wait(lock, [&] { return stop_ || !pending_.empty() || pending_path_; });
        if (stop_) return;
        batch.swap(pending_);
        path.swap(pending_path_);
      }
      if (path) applyPath(*path);
      for (size_t i = 0; i < batch.size(); ++i) handle(*batch[i], i + 1 == batch.size());
      if (batch.size() > 1) {
        searches_skipped_ += batch.size() - 1;
        NODELET_WARN_THROTTLE(
            60.0,
            "loop_detection fell behind: %zu keyframes stored without a loop search (%zu so far); "
            "searched from keyframe %lu, the newest",
            batch.size() - 1, searches_skipped_, static_cast<unsigned long>(batch.back()->id));
      }
    }
  }

  void handle(const osm_graph_slam::KeyFrame& msg, bool search) {
    LoopKeyframe kf;
    kf.id = msg.id;
    const Eigen::Isometry3d odom_pose = fromPoseMsg(msg.odom_pose);
    kf.odom_pose = searchPose(odom_pose);
    kf.accum_distance = msg.accum_distance;
    auto cloud = std::make_shared<PointCloud>();
    std::string error;
    if (!fromPointCloud2(msg.cloud, *cloud, &error)) {
      NODELET_WARN_THROTTLE(10.0, "loop_detection: keyframe %lu cloud not convertible: %s",
                            static_cast<unsigned long>(msg.id), error.c_str());
      return;
    }
    kf.cloud = cloud;
    if (search_in_map_) received_by_stamp_[msg.header.stamp].push_back({msg.id, odom_pose});
    noteRestart(msg);
    if (!search) {
      detector_->addKeyframe(kf);
      return;
    }
    std::optional<DetectedLoop> loop;
    if (mode_ == "odometry" && global_searches_left_ == 0) {
      loop = detector_->process(kf);
    } else {
      const bool after_restart = global_searches_left_ > 0;
      LoopKeyframe query = kf;
      if (after_restart) query.accum_distance = -1.0;  // path length across a restart: meaningless
      loop = detector_->relocalize(query);
      detector_->addKeyframe(kf);
      if (after_restart) global_searches_left_ = loop ? 0 : global_searches_left_ - 1;
    }
    const LoopQueryStats& stats = detector_->lastStats();
    NODELET_DEBUG(
        "loop_detection: keyframe %lu: %d/%d candidates, %.1f ms%s%s",
        static_cast<unsigned long>(msg.id), stats.phase1_candidates, stats.phase2_candidates,
        stats.descriptor_ms + stats.candidates_ms + stats.ranking_ms + stats.verification_ms,
        loop ? "" : ", no loop: ", loop ? "" : stats.reason.c_str());
    if (!loop) return;
    osm_graph_slam::LoopClosurePtr out(new osm_graph_slam::LoopClosure);
    out->header = msg.header;
    out->from_id = loop->from_id;
    out->to_id = loop->to_id;
    out->relative_pose = toMsg(loop->relative_pose);
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) out->information[r * 6 + c] = loop->information(r, c);
    }
    out->descriptor_distance = loop->descriptor_distance;
    out->fitness = loop->fitness;
    NODELET_INFO("loop_detection: loop %lu -> %lu, fitness %.3f, descriptor %.3f",
                 static_cast<unsigned long>(out->from_id), static_cast<unsigned long>(out->to_id),
                 out->fitness, out->descriptor_distance);
    publisher_.publish(osm_graph_slam::LoopClosureConstPtr(out));
  }

  /// After a tracking restart (the stamp went back: a looped bag, a restarted recording) the
  /// odometry pose is where the old pass ended, not where the vehicle is: odometry-mode search
  /// would look in the wrong place and the new pass would hang there (fault_injection.test: 19.8
  /// m off). The next keyframes search every stored one instead.
  void noteRestart(const osm_graph_slam::KeyFrame& msg) {
    const bool went_back = !last_stamp_.isZero() && msg.header.stamp < last_stamp_;
    last_stamp_ = msg.header.stamp;
    if (!went_back || !msg.tracking_recovered || node_params_.relocalize_after_restart <= 0) return;
    global_searches_left_ = node_params_.relocalize_after_restart;
    NODELET_INFO(
        "loop_detection: keyframe %lu follows a tracking restart: up to %d keyframes search all "
        "%zu stored keyframes until a loop places the new pass",
        static_cast<unsigned long>(msg.id), global_searches_left_, detector_->size());
  }

  /// The keyframe in the map (search_frame: map) by the newest map -> odom, else as it came.
  Eigen::Isometry3d searchPose(const Eigen::Isometry3d& odom_pose) {
    if (!search_in_map_) return odom_pose;
    if (!map_to_odom_) {
      // Normal until the back-end's first path; the odometry pose is the best there is.
      NODELET_WARN_ONCE("loop_detection: no slam/path yet: searching around odometry poses");
      return odom_pose;
    }
    return *map_to_odom_ * odom_pose;
  }

  std::string mode_;
  LoopDetectionNodeletParams node_params_;
  bool search_in_map_ = false;  ///< search_frame map
  std::unique_ptr<LoopDetector> detector_;
  ros::Publisher publisher_;
  /// The keyframe subscription's queue (declared before subscriber_: it must outlive it).
  ros::CallbackQueue input_queue_;
  ros::Subscriber subscriber_;
  std::unique_ptr<ros::AsyncSpinner> input_spinner_;
  std::thread worker_;
  std::mutex pending_mutex_;
  std::condition_variable pending_cv_;
  std::deque<osm_graph_slam::KeyFrameConstPtr> pending_;  ///< received, not yet handled
  ros::Subscriber path_subscriber_;                       ///< search_frame map: slam/path
  nav_msgs::PathConstPtr pending_path_;                   ///< the newest, not yet applied
  struct Received {
    uint64_t id;
    Eigen::Isometry3d odom_pose;
  };
  /// Worker only (search_frame map): the keyframes received, by stamp, and map -> odom.
  std::map<ros::Time, std::vector<Received>> received_by_stamp_;
  std::optional<Eigen::Isometry3d> map_to_odom_;
  bool stop_ = false;
  size_t searches_skipped_ = 0;
  SequenceGaps keyframe_ids_;  ///< counts keyframes lost in the subscription queue
  ros::Time last_stamp_;       ///< of the previous keyframe (noteRestart)
  int global_searches_left_ = 0;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::LoopDetectionNodelet, nodelet::Nodelet)
