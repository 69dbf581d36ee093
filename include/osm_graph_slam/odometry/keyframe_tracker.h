#pragma once
// Scan-to-keyframe LiDAR odometry (ART-SLAM thesis §3.1.4): every filtered scan is registered
// against the current keyframe from a constant-velocity guess; a scan becomes the new keyframe
// when it moved, turned or aged more than the thresholds. The registration is GICP on the
// prefiltered scans (the default) or MCS-SLAM's multi-cue photometric registration against
// denser tracker keyframes (`tracker: multi_cue`, thesis §4.1, doc/multi_cue.md). ROS-free.
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/cloud/scan_deskew.h"
#include "osm_graph_slam/multi_cue/multi_cue_registration.h"
#include "osm_graph_slam/odometry/fitness_gate.h"
#include "osm_graph_slam/odometry/pre_tracker.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

class ScanMatcher;

/// The multi-cue tracker (`tracker: multi_cue`): photometric registration of the full-resolution
/// scan's multi-cue image against tracker keyframes, which are made on their own thresholds,
/// apart from the graph's keyframes (those stay as keyframe_delta_* make them).
struct MultiCueTrackingParams {
  MultiCueParams registration;
  /// The LiDAR's spherical image: "hdl64e" (KITTI), "os1_64" (SphericalProjectionParams) or
  /// "auto" (the one whose field of view the first scan fills; logged once).
  std::string sensor = "auto";
  SurfaceContinuityParams continuity;
  /// [m] new tracker keyframe after this, [rad] or this rotation (1 deg): the thesis's. Sparser
  /// references chain fewer matches, each of which comes out ~3 mm short (a bias of the
  /// registration): 2 m / 5 deg gave quick-matrix ATE 1.17x GICP's instead of 1.28x, but on
  /// the real drive a map 37 % less sharp than GICP's instead of 12 % (doc/multi_cue.md).
  double keyframe_delta_trans = 0.5;
  double keyframe_delta_angle = 0.01745;
  /// The fitness gate on the multi-cue fitness (chi2 / inlier pixels: the mean weighted squared
  /// cue error, dominated by the range, ~[m^2]; GICP's limits are in other units). Real KITTI
  /// 0005 (multi_cue_benchmark --trackers): true matches 0.019 median, 0.043 worst; a track that
  /// had diverged scored 0.1-0.36. The adaptive limit is fitness_ratio x the recent median (~0.08).
  double max_fitness = 0.1;
  double fitness_ratio_floor = 0.05;  ///< the adaptive limit never goes below this
};

struct KeyframeTrackerParams {
  /// The scan registration: "gicp" (the prefiltered scan against the graph keyframe with
  /// `registration`) or "multi_cue" (MultiCueTrackingParams). Anything else fails validate().
  std::string tracker = "gicp";
  MultiCueTrackingParams multi_cue;
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
  /// ... or exceeds this many times the median fitness of the last accepted matches (FitnessGate:
  /// a registration in the wrong basin fits far worse than the recent true ones). 0 disables.
  double fitness_ratio = 4.0;
  /// [m^2] the adaptive limit never goes below this. 0.05 rejected true matches of 0.10-0.11 m^2
  /// in the simulator's manoeuvres (median 0.01 there); false matches score 0.8-0.9 m^2.
  double fitness_ratio_floor = 0.2;
  /// A match that moves further than this from the constant-velocity prediction is rejected.
  double max_correction_trans = 2.0;   ///< [m]
  double max_correction_angle = 0.35;  ///< [rad]
  int min_points = 50;                 ///< scans with fewer points are rejected without matching
  /// [s] without a keyframe after which the track counts as lost (logged once, counted; see
  /// TrackingHealth). Above keyframe_delta_time, so a track that keeps matching is never lost.
  double lost_track_after = 3.0;
  /// [s] the motion models extrapolate over a gap in the scans up to this long (a longer gap is
  /// extrapolated this far). Was 5 scan periods: after a 2.1 s dropout in a turn the guess stayed
  /// 10 m short and the match locked 31 deg off (stress matrix, city burst20: 18 m ATE).
  double max_prediction_gap = 3.0;
  /// [s] a scan stamped this much before the last one means the time jumped back (a looped bag,
  /// a restarted recording): tracking restarts there instead of rejecting every later scan. The
  /// keyframe ids and the odom pose continue; smaller steps back are rejected scan by scan.
  /// 0 disables (every stamp not after the last one is rejected).
  double restart_after_jump_back = 5.0;
  /// Initial guess of each match: constant_velocity (the previous motion extrapolated),
  /// pre_tracker (scan-to-previous-scan registration, PreTracker; timed separately), imu (the
  /// rotation since the previous scan from the IMU orientation, translation from constant
  /// velocity) or pre_tracker_imu (the pre-tracker started from the imu guess). Without an IMU
  /// orientation for the scan, imu falls back to constant_velocity, pre_tracker_imu to
  /// pre_tracker. Default imu: on the stress drives (sharp turns at 76 deg/s) constant velocity
  /// accepted matches 25 deg off and ended 48 m off, imu 0.99 m; elsewhere equal (doc/frontend.md).
  std::string guess = "imu";
  PreTrackerParams pre_tracker;
  /// After a failed match, retry from the other guesses: the pre-tracker's, zero motion, and
  /// yaw hypotheses at +-k*recovery_yaw_step about the best guess (k = 1..recovery_yaw_steps).
  bool recovery = true;
  double recovery_yaw_step = 0.26;  ///< [rad] (15 deg)
  int recovery_yaw_steps = 2;
  /// After this many failed matches in a row, re-anchor: the scan becomes a keyframe at the best
  /// guess, flagged so that the back-end links it by a weak odometry edge. 0 disables.
  int reanchor_after_failures = 5;
  /// Motion compensation of each scan (scan_deskew.h) by its predicted motion, before it is
  /// matched and kept as a keyframe. sensor_to_base: the LiDAR's mounting (the prefilter's), to
  /// find each point's azimuth and so its time in the sweep.
  bool deskew = true;
  /// [s] the prediction is taken for the sweep's velocity only if it and the last tracked motion
  /// span at most this: after a dropout (frontend_dropout: 2.1 s through a turn) it is stale, and
  /// the scans are matched as they come until two scans in a row give a velocity again.
  double deskew_max_interval = 0.3;
  SweepTiming sweep;
  Eigen::Isometry3d sensor_to_base = Eigen::Isometry3d::Identity();

  /// "" when the choices are known (tracker, guess, the multi-cue sensor and parameters), else
  /// a sentence saying what is wrong and what is allowed.
  std::string validate() const;
};

enum class TrackStatus {
  kFirstKeyframe,  ///< first scan: became keyframe 0 at the identity pose
  kMatched,        ///< registration accepted
  kMatchFailed,    ///< registration failed/rejected: the prediction was kept (flag raised)
  kRejectedStamp,  ///< stamp not after the last one: ignored, state unchanged
  kRejectedCloud,  ///< empty/too small cloud: ignored, state unchanged
  kReanchored,     ///< matches kept failing: a new keyframe at the best guess (a weak link)
  kRestarted,      ///< the time jumped back: tracking restarted, a new keyframe (a weak link)
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
  /// The new keyframe was re-anchored on a guess after failed matches (not a verified match);
  /// gap: [s] since the previous keyframe.
  bool reanchored = false;
  double gap = 0.0;
  RegistrationResult registration;
  /// [m] where the accepted match lies from the motion model's prediction (the one the scan was
  /// deskewed by), in the scan's base_link: a motion the model missed also distorted the
  /// deskewed scan, so the match is uncertain along it (odometry information, doc/backend.md).
  /// Zero if no match was accepted.
  Eigen::Vector3d prediction_error = Eigen::Vector3d::Zero();
  /// The registration above was against the previous graph keyframe with GICP, so its fitness
  /// and Hessian describe the odometry edge (graph/information.h). False with multi_cue: its
  /// reference may be a tracker keyframe, and its fitness has other units.
  bool registration_is_edge = true;
  /// A remark to log once per run (the tracker sets each only once), e.g. that the scans carry
  /// no intensity and the intensity cue is off.
  std::string notice;
  std::string guess_source;     ///< guess of the accepted match (or of the kept prediction)
  int attempts = 0;             ///< registrations tried against the keyframe
  double pre_tracker_ms = 0.0;  ///< time of the pre-tracker's registration (0 when not run)
  std::string message;          ///< reason when failed or rejected
};

class KeyframeTracker {
 public:
  explicit KeyframeTracker(const KeyframeTrackerParams& params = {});
  ~KeyframeTracker();

  /// Processes one filtered scan (in base_link) taken at stamp [s]. Never throws on bad input.
  /// imu_orientation: base_link's orientation from an IMU at the scan's stamp, in any fixed frame
  /// (an INS attitude, or integrated gyro rates: only its change between scans is used).
  /// sensor_scan: the same scan before the prefilter (full resolution, in the LiDAR's frame),
  /// which the multi_cue tracker projects (a 0.5 m voxel cloud leaves most pixels of its image
  /// empty); ignored by gicp. Without it multi_cue projects `cloud` moved into the LiDAR's frame.
  TrackResult track(double stamp, const PointCloudConstPtr& cloud,
                    const std::optional<Eigen::Quaterniond>& imu_orientation = std::nullopt,
                    const PointCloudConstPtr& sensor_scan = nullptr);

  bool initialized() const { return has_keyframe_; }
  const Eigen::Isometry3d& pose() const { return pose_; }
  const Keyframe& keyframe() const { return keyframe_; }
  uint64_t keyframeCount() const { return has_keyframe_ ? keyframe_.id + 1 : 0; }
  const KeyframeTrackerParams& params() const { return params_; }
  /// Tracker keyframes made so far (multi_cue: the graph's keyframes and those between them;
  /// gicp: the graph's keyframes).
  uint64_t trackerKeyframeCount() const { return tracker_keyframes_; }
  /// The LiDAR's mounting for deskewing, once known (the nodelet reads it from TF).
  void setSensorToBase(const Eigen::Isometry3d& sensor_to_base) {
    params_.sensor_to_base = sensor_to_base;
  }
  void reset();

 private:
  struct Guess {
    const char* source;
    Eigen::Isometry3d pose;  ///< in odom
  };
  /// One scan as the registrations need it: `cloud` the prefiltered scan in base_link (GICP, the
  /// keyframe's cloud), `sensor_scan` the full-resolution one in the LiDAR's frame (multi-cue;
  /// null otherwise). Deskewing moves both.
  struct Scan {
    PointCloudConstPtr cloud;
    PointCloudConstPtr sensor_scan;
    bool operator==(const Scan& o) const { return cloud == o.cloud; }
  };
  Eigen::Isometry3d predict(double stamp) const;
  /// The scan moved to the stamp's frame by the predicted motion (params_.deskew), else the scan.
  Scan deskewed(double stamp, const Scan& scan, const Eigen::Isometry3d& predicted) const;
  /// The scan deskewed by base_link's motion `motion` over dt seconds.
  Scan deskewedBy(const Scan& scan, const Eigen::Isometry3d& motion, double dt) const;
  /// A scan matched without deskewing, deskewed by the motion its match gives and matched again
  /// (relative updated); the raw scan if that match fails.
  Scan deskewedByMatch(double stamp, const Scan& raw, TrackResult& result,
                       Eigen::Isometry3d& relative);
  /// The constant-velocity prediction with its rotation replaced by the IMU's, if both IMU
  /// orientations (this scan's and the previous tracked scan's) are known.
  std::optional<Eigen::Isometry3d> imuPredict(
      const Eigen::Isometry3d& constant_velocity,
      const std::optional<Eigen::Quaterniond>& imu_orientation) const;
  /// Registers against the reference (the scan the matcher holds) from `guess`; true (and
  /// result filled, relative = the scan's pose in the reference) when accepted.
  bool attempt(const Scan& scan, const Guess& guess, TrackResult& result,
               Eigen::Isometry3d& relative);
  /// The pre-tracker's prediction of the scan's pose in odom (computed once per scan).
  std::optional<Eigen::Isometry3d> preTracked(const PointCloudConstPtr& cloud,
                                              const Eigen::Isometry3d& constant_velocity,
                                              TrackResult& result);
  bool acceptMatch(const RegistrationResult& reg, const Eigen::Isometry3d& guess,
                   std::string* reason) const;
  bool needsKeyframe(const Eigen::Isometry3d& relative, double stamp) const;
  /// A graph keyframe at the current pose; it is also the matcher's new reference.
  void makeKeyframe(double stamp, const Scan& scan);
  /// The matcher's reference becomes `scan` at the current pose.
  void setReference(const Scan& scan);
  bool jumpedBack(double stamp) const;
  /// Restarts the motion model at stamp and makes the scan a keyframe at the last pose.
  TrackResult restart(double stamp, const Scan& scan,
                      const std::optional<Eigen::Quaterniond>& imu_orientation);
  /// The matcher's once-per-run remarks, handed to the result.
  void takeNotice(TrackResult& result);

  KeyframeTrackerParams params_;
  std::unique_ptr<ScanMatcher> matcher_;
  double max_fitness_;  ///< params_.max_fitness, or multi_cue's
  Eigen::Isometry3d reference_pose_ = Eigen::Isometry3d::Identity();  ///< the matcher's, in odom
  uint64_t tracker_keyframes_ = 0;
  std::unique_ptr<PreTracker> pre_tracker_;  ///< null unless a guess or the recovery uses it
  bool pre_tracked_ = false;
  std::optional<Eigen::Isometry3d> pre_tracked_pose_;
  int failures_in_row_ = 0;
  FitnessGate fitness_gate_;
  std::optional<Eigen::Quaterniond> last_imu_;  ///< IMU orientation at the last tracked scan
  bool has_keyframe_ = false;
  Keyframe keyframe_;
  Eigen::Isometry3d pose_ = Eigen::Isometry3d::Identity();       ///< last pose in odom
  Eigen::Isometry3d prev_pose_ = Eigen::Isometry3d::Identity();  ///< pose before that
  double last_stamp_ = 0.0;
  double prev_stamp_ = 0.0;
  int poses_seen_ = 0;
  static constexpr int kMaxRawKeyframeDeferrals = 2;  ///< scans after a gap: velocity known again
  int raw_keyframe_deferrals_ = 0;                    ///< scans in a row that could not be deskewed
};

}  // namespace osm_graph_slam
