#include "osm_graph_slam/odometry/keyframe_tracker.h"

#include <cmath>
#include <exception>
#include <sstream>

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
  }
  return "unknown";
}

KeyframeTracker::KeyframeTracker(const KeyframeTrackerParams& params)
    : params_(params), registration_(createRegistration(params.registration)) {}

KeyframeTracker::~KeyframeTracker() = default;

void KeyframeTracker::reset() {
  registration_ = createRegistration(params_.registration);
  has_keyframe_ = false;
  keyframe_ = Keyframe();
  pose_ = prev_pose_ = Eigen::Isometry3d::Identity();
  last_stamp_ = prev_stamp_ = 0.0;
  poses_seen_ = 0;
}

Eigen::Isometry3d KeyframeTracker::predict(double stamp) const {
  if (!params_.constant_velocity_guess || poses_seen_ < 2) return pose_;
  const double dt_prev = last_stamp_ - prev_stamp_;
  const double dt = stamp - last_stamp_;
  const Eigen::Isometry3d motion = prev_pose_.inverse() * pose_;
  const double factor = dt_prev > 1e-9 ? std::min(dt / dt_prev, 5.0) : 1.0;
  return pose_ * scaleMotion(motion, factor);
}

bool KeyframeTracker::acceptMatch(const RegistrationResult& reg, const Eigen::Isometry3d& guess,
                                  std::string* reason) const {
  std::ostringstream why;
  if (!reg.converged) {
    why << "registration failed: " << reg.message;
  } else if (!(reg.fitness <= params_.max_fitness)) {
    why << "fitness " << reg.fitness << " above max_fitness " << params_.max_fitness;
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

bool KeyframeTracker::needsKeyframe(const Eigen::Isometry3d& relative, double stamp) const {
  return relative.translation().norm() >= params_.keyframe_delta_trans ||
         angleOf(relative) >= params_.keyframe_delta_angle ||
         stamp - keyframe_.stamp >= params_.keyframe_delta_time;
}

void KeyframeTracker::makeKeyframe(double stamp, const PointCloudConstPtr& cloud) {
  Keyframe next;
  next.id = has_keyframe_ ? keyframe_.id + 1 : 0;
  next.accum_distance = has_keyframe_ ? keyframe_.accum_distance +
                                            (keyframe_.pose.inverse() * pose_).translation().norm()
                                      : 0.0;
  next.stamp = stamp;
  next.pose = pose_;
  next.cloud = cloud;
  keyframe_ = next;
  has_keyframe_ = true;
  registration_->setTarget(cloud);
}

TrackResult KeyframeTracker::track(double stamp, const PointCloudConstPtr& cloud) {
  TrackResult result;
  result.keyframe_id = keyframe_.id;
  if (!std::isfinite(stamp)) {
    result.status = TrackStatus::kRejectedStamp;
    result.message = "stamp is not finite";
    return result;
  }
  if (has_keyframe_ && stamp <= last_stamp_) {
    std::ostringstream why;
    why.precision(9);
    why << "stamp " << stamp << " is not after the last processed stamp " << last_stamp_;
    result.status = TrackStatus::kRejectedStamp;
    result.message = why.str();
    result.pose = pose_;
    return result;
  }
  if (!cloud || static_cast<int>(cloud->size()) < params_.min_points) {
    result.status = TrackStatus::kRejectedCloud;
    result.message = "cloud has " + std::to_string(cloud ? cloud->size() : 0) +
                     " points, fewer than min_points " + std::to_string(params_.min_points);
    result.pose = pose_;
    return result;
  }

  if (!has_keyframe_) {
    try {
      makeKeyframe(stamp, cloud);
    } catch (const std::exception& e) {
      has_keyframe_ = false;
      result.status = TrackStatus::kRejectedCloud;
      result.message = std::string("could not index the first keyframe: ") + e.what();
      return result;
    }
    last_stamp_ = prev_stamp_ = stamp;
    poses_seen_ = 1;
    result.status = TrackStatus::kFirstKeyframe;
    result.new_keyframe = true;
    result.pose = pose_;
    result.keyframe_id = keyframe_.id;
    return result;
  }

  const Eigen::Isometry3d predicted = predict(stamp);
  const Eigen::Isometry3d guess = keyframe_.pose.inverse() * predicted;
  try {
    result.registration = registration_->align(cloud, guess);
  } catch (const std::exception& e) {
    result.registration = RegistrationResult();
    result.registration.message = std::string("exception: ") + e.what();
  }
  Eigen::Isometry3d relative = guess;
  if (acceptMatch(result.registration, guess, &result.message)) {
    relative = result.registration.transform;
    result.status = TrackStatus::kMatched;
  } else {
    result.status = TrackStatus::kMatchFailed;
  }

  prev_pose_ = pose_;
  prev_stamp_ = last_stamp_;
  pose_ = keyframe_.pose * relative;
  last_stamp_ = stamp;
  ++poses_seen_;
  result.pose = pose_;
  result.relative_to_keyframe = relative;
  result.keyframe_id = keyframe_.id;
  // Only a verified match may become a keyframe: a predicted pose would anchor later scans on
  // a guess.
  if (result.status == TrackStatus::kMatched && needsKeyframe(relative, stamp)) {
    makeKeyframe(stamp, cloud);
    result.new_keyframe = true;
    result.keyframe_id = keyframe_.id;
  }
  return result;
}

}  // namespace osm_graph_slam
