#pragma once
// Scan-to-keyframe LiDAR odometry (ART-SLAM thesis §3.1.4): every filtered scan is registered
// against the current keyframe from a constant-velocity guess; a scan becomes the new keyframe
// when it moved, turned or aged more than the thresholds. ROS-free.
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

struct KeyframeTrackerParams {
  /// Scan-to-keyframe matching uses 2 m correspondences (measured on a simulated drive: with 1 m
  /// the tracker lost 20° of heading in a 20°/s U-turn, ATE over 720 scans 1.6 m -> 0.13 m).
  RegistrationParams registration = [] {
    RegistrationParams r;
    r.max_correspondence_distance = 2.0;
    return r;
  }();
  double keyframe_delta_trans = 2.0;    ///< [m] new keyframe after this translation
  double keyframe_delta_angle = 0.26;   ///< [rad] ... or this rotation
  double keyframe_delta_time = 2.0;     ///< [s] ... or this time
  bool constant_velocity_guess = true;  ///< false: guess = last pose (zero motion)
  /// A match whose fitness (mean squared inlier distance) exceeds this is rejected [m^2].
  double max_fitness = 1.0;
  /// A match that moves further than this from the constant-velocity prediction is rejected.
  double max_correction_trans = 2.0;   ///< [m]
  double max_correction_angle = 0.35;  ///< [rad]
  int min_points = 50;                 ///< scans with fewer points are rejected without matching
  /// [s] without a keyframe after which the track counts as lost (logged once, counted; see
  /// TrackingHealth). Above keyframe_delta_time, so a track that keeps matching is never lost.
  double lost_track_after = 3.0;
};

enum class TrackStatus {
  kFirstKeyframe,  ///< first scan: became keyframe 0 at the identity pose
  kMatched,        ///< registration accepted
  kMatchFailed,    ///< registration failed/rejected: the prediction was kept (flag raised)
  kRejectedStamp,  ///< stamp not after the last one: ignored, state unchanged
  kRejectedCloud,  ///< empty/too small cloud: ignored, state unchanged
};

const char* toString(TrackStatus status);

struct Keyframe {
  uint64_t id = 0;
  double stamp = 0.0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< base_link in odom
  double accum_distance = 0.0;                             ///< [m] since keyframe 0
  PointCloudConstPtr cloud;
};

struct TrackResult {
  TrackStatus status = TrackStatus::kRejectedCloud;
  bool failed() const {
    return status != TrackStatus::kFirstKeyframe && status != TrackStatus::kMatched;
  }
  /// True when the pose below is a fresh estimate (matched, predicted or first keyframe).
  bool has_pose() const {
    return status != TrackStatus::kRejectedStamp && status != TrackStatus::kRejectedCloud;
  }
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< base_link in odom
  Eigen::Isometry3d relative_to_keyframe = Eigen::Isometry3d::Identity();
  uint64_t keyframe_id = 0;  ///< keyframe matched against (the new one if new_keyframe)
  bool new_keyframe = false;
  RegistrationResult registration;
  std::string message;  ///< reason when failed or rejected
};

class KeyframeTracker {
 public:
  explicit KeyframeTracker(const KeyframeTrackerParams& params = {});
  ~KeyframeTracker();

  /// Processes one filtered scan (in base_link) taken at stamp [s]. Never throws on bad input.
  TrackResult track(double stamp, const PointCloudConstPtr& cloud);

  bool initialized() const { return has_keyframe_; }
  const Eigen::Isometry3d& pose() const { return pose_; }
  const Keyframe& keyframe() const { return keyframe_; }
  uint64_t keyframeCount() const { return has_keyframe_ ? keyframe_.id + 1 : 0; }
  const KeyframeTrackerParams& params() const { return params_; }
  void reset();

 private:
  Eigen::Isometry3d predict(double stamp) const;
  bool acceptMatch(const RegistrationResult& reg, const Eigen::Isometry3d& guess,
                   std::string* reason) const;
  bool needsKeyframe(const Eigen::Isometry3d& relative, double stamp) const;
  void makeKeyframe(double stamp, const PointCloudConstPtr& cloud);

  KeyframeTrackerParams params_;
  std::unique_ptr<Registration> registration_;
  bool has_keyframe_ = false;
  Keyframe keyframe_;
  Eigen::Isometry3d pose_ = Eigen::Isometry3d::Identity();       ///< last pose in odom
  Eigen::Isometry3d prev_pose_ = Eigen::Isometry3d::Identity();  ///< pose before that
  double last_stamp_ = 0.0;
  double prev_stamp_ = 0.0;
  int poses_seen_ = 0;
};

}  // namespace osm_graph_slam
