#include "osm_graph_slam/slam/sensor_inputs.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "osm_graph_slam/common/attitude.h"

namespace osm_graph_slam {

SensorInputs::SensorInputs(const SensorInputsParams& params) : params_(params) {}

bool SensorInputs::addOrientation(double stamp, const Eigen::Quaterniond& orientation) {
  const double norm = orientation.norm();
  if (!std::isfinite(stamp) || !std::isfinite(norm) || norm < 1e-6) return false;
  AttitudeSample sample;
  sample.stamp = stamp;
  sample.orientation = orientation.normalized();
  const Eigen::Matrix3d R = sample.orientation.toRotationMatrix();
  const Eigen::Vector2d roll_pitch = rollPitchOf(R);
  sample.roll = roll_pitch.x();
  sample.pitch = roll_pitch.y();
  sample.yaw = yawOf(R);
  std::lock_guard<std::mutex> lock(mutex_);
  const auto at = std::upper_bound(attitudes_.begin(), attitudes_.end(), stamp,
                                   [](double t, const AttitudeSample& s) { return t < s.stamp; });
  attitudes_.insert(at, sample);
  if (params_.max_samples > 0 && attitudes_.size() > params_.max_samples) attitudes_.pop_front();
  return true;
}

bool SensorInputs::addFix(const GnssFixSample& fix) {
  if (!std::isfinite(fix.stamp) || !std::isfinite(fix.lat) || !std::isfinite(fix.lon)) return false;
  std::lock_guard<std::mutex> lock(mutex_);
  if (!keep_fixes_) return true;
  fixes_.insert(std::upper_bound(fixes_.begin(), fixes_.end(), fix,
                                 [](const GnssFixSample& a, const GnssFixSample& b) {
                                   return a.stamp < b.stamp;
                                 }),
                fix);
  if (params_.max_samples > 0 && fixes_.size() > params_.max_samples) fixes_.erase(fixes_.begin());
  return true;
}

void SensorInputs::stopKeepingFixes() {
  std::lock_guard<std::mutex> lock(mutex_);
  keep_fixes_ = false;
  fixes_.clear();
}

void SensorInputs::setOrigin(double lat, double lon, double alt) {
  std::lock_guard<std::mutex> lock(mutex_);
  altitude_known_ = std::isfinite(alt);
  origin_altitude_ = altitude_known_ ? alt : 0.0;
  enu_.emplace(lat, lon, origin_altitude_);
}

std::optional<AttitudeSample> SensorInputs::attitudeAt(double stamp) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto after =
      std::lower_bound(attitudes_.begin(), attitudes_.end(), stamp,
                       [](const AttitudeSample& s, double t) { return s.stamp < t; });
  std::optional<AttitudeSample> best;
  double best_dt = params_.imu_max_time_difference;
  // The nearest is one of the two around stamp; on a tie the later wins.
  for (auto it : {after == attitudes_.begin() ? attitudes_.end() : std::prev(after), after}) {
    if (it == attitudes_.end()) continue;
    const double dt = std::abs(it->stamp - stamp);
    if (dt <= best_dt) {
      best_dt = dt;
      best = *it;
    }
  }
  return best;
}

std::optional<AttitudeSample> SensorInputs::latestAttitudeBefore(double stamp,
                                                                 double max_age) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto after =
      std::upper_bound(attitudes_.begin(), attitudes_.end(), stamp,
                       [](double t, const AttitudeSample& s) { return t < s.stamp; });
  if (after == attitudes_.begin()) return std::nullopt;
  const AttitudeSample& newest = *std::prev(after);
  if (stamp - newest.stamp > max_age) return std::nullopt;
  return newest;
}

std::optional<AttitudeSample> SensorInputs::firstAttitude() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (attitudes_.empty()) return std::nullopt;
  return attitudes_.front();
}

std::optional<GnssFixSample> SensorInputs::fixAt(double stamp) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return gnssFixAt(fixes_, stamp, params_.gnss_max_gap, params_.gnss_max_time_difference);
}

std::optional<GnssPosition> SensorInputs::gnssPositionAt(double stamp) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!enu_) return std::nullopt;
  const auto fix = gnssFixAt(fixes_, stamp, params_.gnss_max_gap, params_.gnss_max_time_difference);
  if (!fix) return std::nullopt;
  // One conversion at the fix's own altitude when known (as offline_slam's drive sources do),
  // else at the origin's, so that x and y do not depend on an unknown height.
  const bool has_altitude = altitude_known_ && std::isfinite(fix->alt);
  const Eigen::Vector3d enu =
      enu_->toEnu(fix->lat, fix->lon, has_altitude ? fix->alt : origin_altitude_);
  GnssPosition out{enu.head<2>(), fix->std_xy, std::nullopt};
  if (has_altitude) out.altitude = enu.z();
  return out;
}

size_t SensorInputs::numAttitudes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return attitudes_.size();
}

size_t SensorInputs::numFixes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return fixes_.size();
}

InitialHeading SensorInputs::initialHeading(double stamp) const {
  InitialHeading out;
  if (const auto at = attitudeAt(stamp)) {
    out.yaw = at->yaw;
    return out;
  }
  std::ostringstream msg;
  if (const auto before = latestAttitudeBefore(stamp, params_.initial_heading_max_age)) {
    // Still far better than none (the odometry frame's, e.g. 70 deg off on KITTI drive 0005).
    out.yaw = before->yaw;
    msg << "no IMU sample within " << params_.imu_max_time_difference
        << " s of the first keyframe: its heading is the one " << stamp - before->stamp
        << " s before it";
  } else if (numAttitudes() > 0) {
    msg << "no IMU sample within " << params_.initial_heading_max_age
        << " s before the first keyframe: no initial heading from the IMU";
  }
  out.warning = msg.str();
  return out;
}

}  // namespace osm_graph_slam
