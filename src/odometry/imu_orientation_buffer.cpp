#include "osm_graph_slam/odometry/imu_orientation_buffer.h"

#include <algorithm>
#include <cmath>

namespace osm_graph_slam {

ImuOrientationBuffer::ImuOrientationBuffer(double max_gap, size_t capacity)
    : max_gap_(max_gap), capacity_(std::max<size_t>(capacity, 2)) {}

void ImuOrientationBuffer::push(double stamp, const Eigen::Quaterniond& q) {
  if (!std::isfinite(stamp) || !q.coeffs().allFinite() || q.norm() < 1e-6) return;
  if (!samples_.empty() && stamp <= samples_.back().stamp) return;  // out of order: ignored
  samples_.push_back({stamp, q.normalized()});
  if (samples_.size() > capacity_) samples_.pop_front();
}

void ImuOrientationBuffer::clear() {
  samples_.clear();
  last_rate_.reset();
}

void ImuOrientationBuffer::addOrientation(double stamp, const Eigen::Quaterniond& orientation) {
  last_rate_.reset();
  push(stamp, orientation);
}

void ImuOrientationBuffer::addAngularVelocity(double stamp, const Eigen::Vector3d& rate) {
  if (!rate.allFinite()) return;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  if (!samples_.empty() && last_rate_) {
    const double dt = stamp - samples_.back().stamp;
    if (dt <= 0.0) return;
    // Trapezoid over the interval; a gap resets nothing, the delta just gets less accurate.
    const Eigen::Vector3d w = 0.5 * (*last_rate_ + rate) * dt;
    const double angle = w.norm();
    const Eigen::Quaterniond step = angle > 1e-12
                                        ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle))
                                        : Eigen::Quaterniond::Identity();
    q = samples_.back().orientation * step;
  }
  last_rate_ = rate;
  push(stamp, q);
}

std::optional<Eigen::Quaterniond> ImuOrientationBuffer::orientationAt(double stamp) const {
  if (samples_.empty()) return std::nullopt;
  auto after = std::lower_bound(samples_.begin(), samples_.end(), stamp,
                                [](const Sample& s, double t) { return s.stamp < t; });
  if (after == samples_.begin()) {
    if (after->stamp - stamp > max_gap_) return std::nullopt;
    return after->orientation;
  }
  const auto before = std::prev(after);
  if (after == samples_.end()) {
    if (stamp - before->stamp > max_gap_) return std::nullopt;
    return before->orientation;
  }
  if (after->stamp - before->stamp > 2.0 * max_gap_) return std::nullopt;
  const double w = (stamp - before->stamp) / (after->stamp - before->stamp);
  return before->orientation.slerp(w, after->orientation);
}

}  // namespace osm_graph_slam
