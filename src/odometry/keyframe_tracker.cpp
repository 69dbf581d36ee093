#include "osm_graph_slam/odometry/keyframe_tracker.h"

#include <cmath>
#include <exception>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "scan_matcher.h"

namespace osm_graph_slam {
namespace {

double angleOf(const Eigen::Isometry3d& t) {
  return Eigen::AngleAxisd(t.linear()).angle();
}

/// The motion scaled by factor on SE(3) (rotation angle and translation scaled together).
Eigen::Isometry3d scaleMotion(const Eigen::Isometry3d& motion, double factor) {
  const Eigen::AngleAxisd aa(motion.linear());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(aa.angle() * factor, aa.axis()).toRotationMatrix();
  out.translation() = motion.translation() * factor;
  return out;
}

}  // namespace

const char* toString(TrackStatus status) {
  switch (status) {
    case TrackStatus::kFirstKeyframe:
      return "first_keyframe";
    case TrackStatus::kMatched:
      return "matched";
    case TrackStatus::kMatchFailed:
      return "match_failed";
    case TrackStatus::kRejectedStamp:
      return "rejected_stamp";
    case TrackStatus::kRejectedCloud:
      return "rejected_cloud";
    case TrackStatus::kReanchored:
      return "reanchored";
    case TrackStatus::kRestarted:
      return "restarted";
  }
  return "unknown";
}

std::string KeyframeTrackerParams::validate() const {
  if (tracker != "gicp" && tracker != "multi_cue")
    return "unknown tracker '" + tracker + "' (gicp | multi_cue)";
  if (guess != "constant_velocity" && guess != "pre_tracker" && guess != "imu" &&
      guess != "pre_tracker_imu")
    return "unknown guess '" + guess +
           "' (constant_velocity | pre_tracker | imu | pre_tracker_imu)";
  if (tracker != "multi_cue") return "";
  if (multi_cue.sensor != "auto" && multi_cue.sensor != "hdl64e" && multi_cue.sensor != "os1_64")
    return "unknown multi_cue_sensor '" + multi_cue.sensor + "' (auto | hdl64e | os1_64)";
  if (const std::string why = multi_cue.registration.validate(); !why.empty())
    return "multi_cue: " + why;
  if (!(multi_cue.keyframe_delta_trans > 0.0) || !(multi_cue.keyframe_delta_angle > 0.0))
    return "multi_cue_keyframe_delta_trans and _angle must be positive";
  return "";
}

KeyframeTracker::KeyframeTracker(const KeyframeTrackerParams& params)
    : params_(params),
      matcher_(createScanMatcher(params)),  // throws for an unknown choice
      max_fitness_(params.tracker == "multi_cue" ? params.multi_cue.max_fitness
                                                 : params.max_fitness),
      fitness_gate_(params.fitness_ratio, params.tracker == "multi_cue"
                                              ? params.multi_cue.fitness_ratio_floor
                                              : params.fitness_ratio_floor) {
  if (params_.guess.rfind("pre_tracker", 0) == 0 || params_.recovery)
    pre_tracker_ = std::make_unique<PreTracker>(params_.pre_tracker, params_.registration);
}

KeyframeTracker::~KeyframeTracker() = default;

void KeyframeTracker::reset() {
  matcher_ = createScanMatcher(params_);
  reference_pose_ = Eigen::Isometry3d::Identity();
  tracker_keyframes_ = 0;
  has_keyframe_ = false;
  keyframe_ = Keyframe();
  pose_ = prev_pose_ = Eigen::Isometry3d::Identity();
  last_stamp_ = prev_stamp_ = 0.0;
  poses_seen_ = 0;
  raw_keyframe_deferrals_ = 0;
  failures_in_row_ = 0;
  fitness_gate_.clear();
  last_imu_.reset();
  if (pre_tracker_) pre_tracker_->reset();
}

Eigen::Isometry3d KeyframeTracker::predict(double stamp) const {
  if (!params_.constant_velocity_guess || poses_seen_ < 2) return pose_;
  const double dt_prev = last_stamp_ - prev_stamp_;
  const double dt = std::min(stamp - last_stamp_, params_.max_prediction_gap);
  const Eigen::Isometry3d motion = prev_pose_.inverse() * pose_;
  const double factor = dt_prev > 1e-9 ? dt / dt_prev : 1.0;
  return pose_ * scaleMotion(motion, factor);
}

bool KeyframeTracker::acceptMatch(const RegistrationResult& reg, const Eigen::Isometry3d& guess,
                                  std::string* reason) const {
  std::ostringstream why;
  if (!reg.converged) {
    why << "registration failed: " << reg.message;
  } else if (!(reg.fitness <= max_fitness_)) {
    why << "fitness " << reg.fitness << " above max_fitness " << max_fitness_;
  } else if (!fitness_gate_.accepts(reg.fitness)) {
    why << "fitness " << reg.fitness << " above " << params_.fitness_ratio
        << " x the recent median (limit " << fitness_gate_.limit() << ")";
  } else {
    const Eigen::Isometry3d correction = guess.inverse() * reg.transform;
    const double dt = correction.translation().norm();
    const double da = angleOf(correction);
    if (dt > params_.max_correction_trans || da > params_.max_correction_angle) {
      why << "correction from the prediction too large (" << dt << " m, " << da << " rad)";
    } else {
      return true;
    }
  }
  *reason = why.str();
  return false;
}

bool KeyframeTracker::attempt(const Scan& scan, const Guess& guess, TrackResult& result,
                              Eigen::Isometry3d& relative) {
  const Eigen::Isometry3d guess_relative = reference_pose_.inverse() * guess.pose;
  RegistrationResult reg;
  try {
    reg = matcher_->align({scan.cloud, scan.sensor_scan, params_.sensor_to_base}, guess_relative);
  } catch (const std::exception& e) {
    reg.message = std::string("exception: ") + e.what();
  }
  ++result.attempts;
  std::string reason;
  const bool accepted = acceptMatch(reg, guess_relative, &reason);
  if (result.attempts == 1 || accepted) {
    result.registration = reg;
    result.message = reason;
  }
  if (!accepted) return false;
  relative = reg.transform;
  result.guess_source = guess.source;
  return true;
}

std::optional<Eigen::Isometry3d> KeyframeTracker::preTracked(
    const PointCloudConstPtr& cloud, const Eigen::Isometry3d& constant_velocity,
    TrackResult& result) {
  if (pre_tracked_ || !pre_tracker_) return pre_tracked_pose_;
  pre_tracked_ = true;
  // The scan-to-scan motion, starting from the motion model. Not bounded by the tracker's
  // fitness limit (other units, see PreTracker::estimate): the match from this guess is.
  if (const auto e = pre_tracker_->estimate(cloud, pose_.inverse() * constant_velocity)) {
    result.pre_tracker_ms = e->time_ms;
    pre_tracked_pose_ = pose_ * e->motion;
  }
  return pre_tracked_pose_;
}

bool KeyframeTracker::needsKeyframe(const Eigen::Isometry3d& relative, double stamp) const {
  return relative.translation().norm() >= params_.keyframe_delta_trans ||
         angleOf(relative) >= params_.keyframe_delta_angle ||
         stamp - keyframe_.stamp >= params_.keyframe_delta_time;
}

void KeyframeTracker::setReference(const Scan& scan) {
  matcher_->setReference({scan.cloud, scan.sensor_scan, params_.sensor_to_base});
  reference_pose_ = pose_;
  ++tracker_keyframes_;
}

void KeyframeTracker::takeNotice(TrackResult& result) {
  const std::string notice = matcher_->takeNotice();
  if (!notice.empty()) result.notice += (result.notice.empty() ? "" : "; ") + notice;
}

void KeyframeTracker::makeKeyframe(double stamp, const Scan& scan) {
  Keyframe next;
  next.id = has_keyframe_ ? keyframe_.id + 1 : 0;
  next.accum_distance = has_keyframe_ ? keyframe_.accum_distance +
                                            (keyframe_.pose.inverse() * pose_).translation().norm()
                                      : 0.0;
  next.stamp = stamp;
  next.pose = pose_;
  next.cloud = scan.cloud;
  setReference(scan);  // first: a cloud that cannot serve leaves the keyframe as it was
  keyframe_ = next;
  has_keyframe_ = true;
}

std::optional<Eigen::Isometry3d> KeyframeTracker::imuPredict(
    const Eigen::Isometry3d& constant_velocity,
    const std::optional<Eigen::Quaterniond>& imu_orientation) const {
  if (!imu_orientation || !last_imu_) return std::nullopt;
  Eigen::Isometry3d motion = pose_.inverse() * constant_velocity;
  const Eigen::Quaterniond imu_rotation = (last_imu_->conjugate() * *imu_orientation).normalized();
  // A circular arc at constant speed: the chord of a turn by angle a points a/2 off the start
  // heading and is sinc(a/2) times the path. Constant velocity aimed it at half of the previous
  // period's rotation; re-aim it at half the IMU's (matters across a gap in a turn).
  const Eigen::AngleAxisd cv(motion.linear()), imu(imu_rotation);
  auto sinc = [](double x) { return std::abs(x) < 1e-6 ? 1.0 : std::sin(x) / x; };
  const Eigen::Quaterniond half_cv(Eigen::AngleAxisd(0.5 * cv.angle(), cv.axis()));
  const Eigen::Quaterniond half_imu(Eigen::AngleAxisd(0.5 * imu.angle(), imu.axis()));
  motion.translation() = (sinc(0.5 * imu.angle()) / sinc(0.5 * cv.angle())) *
                         (half_imu * (half_cv.conjugate() * motion.translation()));
  motion.linear() = imu_rotation.toRotationMatrix();
  return pose_ * motion;
}

bool KeyframeTracker::jumpedBack(double stamp) const {
  return has_keyframe_ && params_.restart_after_jump_back > 0.0 &&
         stamp < last_stamp_ - params_.restart_after_jump_back;
}

TrackResult KeyframeTracker::restart(double stamp, const Scan& scan,
                                     const std::optional<Eigen::Quaterniond>& imu_orientation) {
  // Nothing of the old motion model holds across the jump (velocity, fitness level, IMU and
  // pre-tracker references); the keyframe ids and the pose continue so that the back-end keeps
  // its map and links the new keyframe weakly, as after a re-anchor.
  std::ostringstream why;
  why << "time jumped back " << std::fixed << std::setprecision(3) << last_stamp_ - stamp
      << " s (stamp " << stamp << " after " << last_stamp_
      << "): tracking restarted, the new keyframe continues from the last pose";
  TrackResult result;
  try {
    makeKeyframe(stamp, scan);
  } catch (const std::exception& e) {
    result.status = TrackStatus::kRejectedCloud;
    result.message = std::string("could not index the restart keyframe: ") + e.what();
    result.pose = pose_;
    return result;
  }
  prev_pose_ = pose_;
  last_stamp_ = prev_stamp_ = stamp;
  poses_seen_ = 1;
  failures_in_row_ = 0;
  fitness_gate_.clear();
  last_imu_ = imu_orientation;
  if (pre_tracker_) {
    pre_tracker_->reset();
    pre_tracker_->remember(scan.cloud);
  }
  result.status = TrackStatus::kRestarted;
  result.new_keyframe = result.reanchored = true;
  result.pose = pose_;
  result.keyframe_id = keyframe_.id;
  result.message = why.str();
  return result;
}

KeyframeTracker::Scan KeyframeTracker::deskewedBy(const Scan& scan, const Eigen::Isometry3d& motion,
                                                  double dt) const {
  Scan out;
  out.cloud = deskewedCopy(*scan.cloud, params_.sensor_to_base, motion, dt, params_.sweep);
  // The full-resolution scan is in the LiDAR's frame: the same motion seen from there.
  if (scan.sensor_scan) {
    const Eigen::Isometry3d& s = params_.sensor_to_base;
    out.sensor_scan =
        deskewedScanBySector(*scan.sensor_scan, s.inverse() * motion * s, dt, params_.sweep);
  }
  return out;
}

KeyframeTracker::Scan KeyframeTracker::deskewed(double stamp, const Scan& scan,
                                                const Eigen::Isometry3d& predicted) const {
  // The predicted motion to this scan (constant velocity, its rotation from the IMU when the
  // guess uses it) is centred half a period before the sweep; the last tracked motion would be a
  // period and a half before it, and lag behind every change of speed or turn rate.
  const double dt = stamp - last_stamp_, dt_prev = last_stamp_ - prev_stamp_;
  const bool recent = dt > 1e-9 && dt <= params_.deskew_max_interval && dt_prev > 1e-9 &&
                      dt_prev <= params_.deskew_max_interval;
  if (!params_.deskew || poses_seen_ < 2 || !recent) return scan;
  return deskewedBy(scan, pose_.inverse() * predicted, dt);
}

KeyframeTracker::Scan KeyframeTracker::deskewedByMatch(double stamp, const Scan& raw,
                                                       TrackResult& result,
                                                       Eigen::Isometry3d& relative) {
  // A scan matched as it came (after a gap, or the second of the drive: no velocity known): its
  // match gives the mean motion since the last scan. Deskewed by that, it is matched again from
  // there (frontend_dropout, 2.1 s hole in a turn: the raw first scan was 0.17 m off).
  const double dt = stamp - last_stamp_;
  if (!params_.deskew || !(dt > 1e-9) || dt > params_.max_prediction_gap) return raw;
  const Eigen::Isometry3d matched = reference_pose_ * relative;
  const Scan moved = deskewedBy(raw, pose_.inverse() * matched, dt);
  Eigen::Isometry3d again = relative;
  if (!attempt(moved, {"deskewed_by_match", matched}, result, again)) return raw;
  relative = again;
  return moved;
}

TrackResult KeyframeTracker::track(double stamp, const PointCloudConstPtr& raw_cloud,
                                   const std::optional<Eigen::Quaterniond>& imu_orientation,
                                   const PointCloudConstPtr& sensor_scan) {
  TrackResult result;
  result.keyframe_id = keyframe_.id;
  result.registration_is_edge = matcher_->registrationIsEdge();
  // GICP never reads the full-resolution scan: it is not deskewed for nothing.
  const Scan raw{raw_cloud, params_.tracker == "multi_cue" ? sensor_scan : nullptr};
  if (!std::isfinite(stamp)) {
    result.status = TrackStatus::kRejectedStamp;
    result.message = "stamp is not finite";
    return result;
  }
  const bool cloud_ok = raw_cloud && static_cast<int>(raw_cloud->size()) >= params_.min_points;
  if (cloud_ok && jumpedBack(stamp)) return restart(stamp, raw, imu_orientation);
  if (has_keyframe_ && stamp <= last_stamp_) {
    std::ostringstream why;
    why << std::fixed << std::setprecision(3) << "stamp " << stamp
        << " is not after the last processed stamp " << last_stamp_;
    result.status = TrackStatus::kRejectedStamp;
    result.message = why.str();
    result.pose = pose_;
    return result;
  }
  if (!cloud_ok) {
    result.status = TrackStatus::kRejectedCloud;
    result.message = "cloud has " + std::to_string(raw_cloud ? raw_cloud->size() : 0) +
                     " points, fewer than min_points " + std::to_string(params_.min_points);
    result.pose = pose_;
    return result;
  }
  if (!has_keyframe_) {
    const Scan& scan = raw;  // no motion known yet to deskew it
    try {
      makeKeyframe(stamp, scan);
    } catch (const std::exception& e) {
      has_keyframe_ = false;
      result.status = TrackStatus::kRejectedCloud;
      result.message = std::string("could not index the first keyframe: ") + e.what();
      return result;
    }
    last_stamp_ = prev_stamp_ = stamp;
    poses_seen_ = 1;
    last_imu_ = imu_orientation;
    if (pre_tracker_) pre_tracker_->remember(scan.cloud);
    takeNotice(result);
    result.status = TrackStatus::kFirstKeyframe;
    result.new_keyframe = true;
    result.pose = pose_;
    result.keyframe_id = keyframe_.id;
    return result;
  }

  const Eigen::Isometry3d constant_velocity = predict(stamp);
  pre_tracked_ = false;
  pre_tracked_pose_.reset();
  const std::optional<Eigen::Isometry3d> imu = imuPredict(constant_velocity, imu_orientation);
  const bool imu_guess = params_.guess == "imu" || params_.guess == "pre_tracker_imu";
  // The pre-tracker starts from the best motion model at hand.
  const Eigen::Isometry3d motion_model = imu_guess && imu ? *imu : constant_velocity;
  Scan scan = deskewed(stamp, raw, motion_model);
  Guess best{imu_guess && imu ? "imu" : "constant_velocity", motion_model};
  if (params_.guess.rfind("pre_tracker", 0) == 0)
    if (const auto p = preTracked(scan.cloud, motion_model, result)) best = {"pre_tracker", *p};

  // relative: the scan's pose in the matcher's reference (the graph keyframe with GICP).
  Eigen::Isometry3d relative = reference_pose_.inverse() * best.pose;
  bool matched = attempt(scan, best, result, relative);
  const std::string first_failure = result.message;
  if (!matched && params_.recovery) {
    // Other guesses, most likely first; the best of them is kept if every one fails.
    std::vector<Guess> retries;
    if (imu && !imu_guess) retries.push_back({"imu", *imu});
    if (best.source != std::string("pre_tracker")) {
      if (const auto p = preTracked(scan.cloud, motion_model, result)) {
        best = {"pre_tracker", *p};
        retries.push_back(best);
      }
    }
    if (best.source != std::string("constant_velocity"))
      retries.push_back({"constant_velocity", constant_velocity});
    retries.push_back({"zero_motion", pose_});
    for (int k = 1; k <= params_.recovery_yaw_steps; ++k)
      for (const double sign : {1.0, -1.0}) {
        Guess g{"yaw_hypothesis", best.pose};
        g.pose.linear() =
            best.pose.linear() *
            Eigen::AngleAxisd(sign * k * params_.recovery_yaw_step, Eigen::Vector3d::UnitZ())
                .toRotationMatrix();
        retries.push_back(g);
      }
    for (const Guess& g : retries)
      if ((matched = attempt(scan, g, result, relative))) break;
    if (!matched) relative = reference_pose_.inverse() * best.pose;
  }
  if (matched) {
    result.status = TrackStatus::kMatched;
    failures_in_row_ = 0;
    fitness_gate_.add(result.registration.fitness);
  } else {
    result.status = TrackStatus::kMatchFailed;
    result.guess_source = best.source;
    result.message =
        first_failure + (result.attempts > 1 ? " (and " + std::to_string(result.attempts - 1) +
                                                   " retries from other guesses)"
                                             : std::string());
    ++failures_in_row_;
  }
  if (matched && scan == raw) scan = deskewedByMatch(stamp, raw, result, relative);

  prev_pose_ = pose_;
  prev_stamp_ = last_stamp_;
  pose_ = reference_pose_ * relative;
  const Eigen::Isometry3d to_keyframe = keyframe_.pose.inverse() * pose_;
  if (matched) result.prediction_error = (motion_model.inverse() * pose_).translation();
  last_stamp_ = stamp;
  last_imu_ = imu_orientation;
  ++poses_seen_;
  result.pose = pose_;
  result.relative_to_keyframe = to_keyframe;
  result.keyframe_id = keyframe_.id;
  if (pre_tracker_) pre_tracker_->remember(scan.cloud);
  // Only a verified match may become a keyframe: a predicted pose would anchor later scans on
  // a guess. The exception is re-anchoring after failures in a row, flagged for the back-end:
  // without it the keyframe falls ever further behind and the rest of the drive is lost.
  // A scan that could not be deskewed (just after a gap) makes a poor keyframe: every later
  // scan would be matched against its smear. It waits up to kMaxRawKeyframeDeferrals scans for
  // one that can (frontend_dropout, 2.1 s hole: 0.17 m error after the gap without the wait).
  // The same holds for the multi-cue tracker's own keyframes, made between the graph's.
  const bool not_deskewed = params_.deskew && scan == raw;
  raw_keyframe_deferrals_ = not_deskewed ? raw_keyframe_deferrals_ + 1 : 0;
  const bool defer = not_deskewed && raw_keyframe_deferrals_ <= kMaxRawKeyframeDeferrals;
  if (matched && !defer && needsKeyframe(to_keyframe, stamp)) {
    makeKeyframe(stamp, scan);
    result.new_keyframe = true;
    result.keyframe_id = keyframe_.id;
  } else if (matched && !defer && matcher_->wantsReference(relative)) {
    setReference(scan);
  } else if (!matched && params_.reanchor_after_failures > 0 &&
             failures_in_row_ >= params_.reanchor_after_failures) {
    result.gap = stamp - keyframe_.stamp;
    makeKeyframe(stamp, scan);
    result.status = TrackStatus::kReanchored;
    result.new_keyframe = result.reanchored = true;
    result.keyframe_id = keyframe_.id;
    result.message += "; re-anchored on the " + std::string(best.source) + " guess after " +
                      std::to_string(failures_in_row_) + " failed matches";
    failures_in_row_ = 0;
    // The place may have changed (vegetation, open ground: true matches fit worse there); the
    // adaptive gate learns the new fitness level from the next matches instead of rejecting
    // them against the old one.
    fitness_gate_.clear();
  }
  takeNotice(result);
  return result;
}

}  // namespace osm_graph_slam
