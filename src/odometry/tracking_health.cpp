#include "osm_graph_slam/odometry/tracking_health.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace osm_graph_slam {

const char* toString(TrackingState state) {
  return state == TrackingState::kOk ? "ok" : "lost";
}

TrackingHealth::TrackingHealth(double lost_after) : lost_after_(lost_after) {}

double TrackingHealth::timeSinceKeyframe() const {
  return last_keyframe_stamp_ ? std::max(0.0, latest_stamp_ - *last_keyframe_stamp_) : 0.0;
}

TrackingStats TrackingHealth::stats() const {
  TrackingStats s = stats_;
  s.longest_no_keyframe_s = std::max(s.longest_no_keyframe_s, timeSinceKeyframe());
  return s;
}

std::optional<TrackingEvent> TrackingHealth::update(double stamp, const TrackResult& result) {
  recovery_gap_.reset();
  switch (result.status) {
    case TrackStatus::kFirstKeyframe:
    case TrackStatus::kMatched:
      ++stats_.matched;
      failures_in_row_ = 0;
      break;
    case TrackStatus::kMatchFailed:
      ++stats_.failed_matches;
      ++failures_in_row_;
      break;
    case TrackStatus::kReanchored:
      ++stats_.failed_matches;
      ++stats_.reanchors;
      failures_in_row_ = 0;
      break;
    case TrackStatus::kRejectedStamp:
    case TrackStatus::kRejectedCloud:
      return updateRejected(stamp, result.message);
    case TrackStatus::kRestarted:
      return restarted(stamp, result);
  }
  ++stats_.scans;
  if (stats_.scans == 1) stats_.first_stamp = stamp;
  stats_.last_stamp = std::max(stats_.last_stamp, stamp);
  latest_stamp_ = std::max(latest_stamp_, stamp);
  if (!result.new_keyframe) return checkGap(stamp, result.message);

  ++stats_.keyframes;
  std::optional<TrackingEvent> event;
  if (last_keyframe_stamp_) {
    const double gap = stamp - *last_keyframe_stamp_;
    stats_.longest_no_keyframe_s = std::max(stats_.longest_no_keyframe_s, gap);
    if (result.reanchored || state_ == TrackingState::kLost) recovery_gap_ = gap;
    if (result.reanchored && state_ != TrackingState::kLost) {
      // Each re-anchor is a link the back-end only knows weakly: say where it happened.
      char buf[512];
      std::snprintf(buf, sizeof(buf),
                    "tracking re-anchored at scan %zu (stamp %.3f): keyframe %llu placed on a "
                    "guess %.1f s after the last verified one (%s)",
                    stats_.scans - 1, stamp, static_cast<unsigned long long>(result.keyframe_id),
                    gap, result.message.c_str());
      event = TrackingEvent{TrackingState::kOk, buf};
    } else if (state_ == TrackingState::kLost) {
      char buf[256];
      std::snprintf(buf, sizeof(buf),
                    "tracking recovered at scan %zu (stamp %.3f): keyframe %llu after %.1f s "
                    "without one%s",
                    stats_.scans - 1, stamp, static_cast<unsigned long long>(result.keyframe_id),
                    gap,
                    result.reanchored ? " (re-anchored on a guess: a weak odometry link)" : "");
      event = TrackingEvent{TrackingState::kOk, buf};
    }
  }
  state_ = TrackingState::kOk;
  last_keyframe_stamp_ = stamp;
  return event;
}

std::optional<TrackingEvent> TrackingHealth::restarted(double stamp, const TrackResult& result) {
  // The spans without a keyframe restart with the stamps; a lost state ends with the new keyframe.
  recovery_gap_.reset();
  stats_.longest_no_keyframe_s = std::max(stats_.longest_no_keyframe_s, timeSinceKeyframe());
  ++stats_.scans;
  ++stats_.keyframes;
  ++stats_.restarts;
  failures_in_row_ = 0;
  latest_stamp_ = stamp;  // stats_.last_stamp stays the latest of all
  last_keyframe_stamp_ = stamp;
  state_ = TrackingState::kOk;
  char buf[512];
  std::snprintf(buf, sizeof(buf), "tracking restart %zu at scan %zu: %s (keyframe %llu)",
                stats_.restarts, stats_.scans - 1, result.message.c_str(),
                static_cast<unsigned long long>(result.keyframe_id));
  return TrackingEvent{TrackingState::kOk, buf};
}

std::optional<TrackingEvent> TrackingHealth::updateRejected(double stamp,
                                                            const std::string& reason) {
  recovery_gap_.reset();
  ++stats_.scans;
  ++stats_.rejected_scans;
  if (stats_.scans == 1) stats_.first_stamp = stamp;
  stats_.last_stamp = std::max(stats_.last_stamp, stamp);
  latest_stamp_ = std::max(latest_stamp_, stamp);
  return checkGap(stamp, reason);
}

std::optional<TrackingEvent> TrackingHealth::checkGap(double stamp, const std::string& reason) {
  if (!last_keyframe_stamp_) return std::nullopt;
  if (state_ == TrackingState::kLost) {
    ++stats_.scans_while_lost;
    return std::nullopt;
  }
  const double gap = stamp - *last_keyframe_stamp_;
  if (gap <= lost_after_) return std::nullopt;
  state_ = TrackingState::kLost;
  ++stats_.lost_events;
  ++stats_.scans_while_lost;
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "tracking lost at scan %zu (stamp %.3f): no keyframe for %.1f s (limit %.1f s), "
                "%zu failed matches in a row; last reason: %s",
                stats_.scans - 1, stamp, gap, lost_after_, failures_in_row_,
                reason.empty() ? "none given" : reason.c_str());
  return TrackingEvent{TrackingState::kLost, buf};
}

const char* toString(TrackingHealthLevel level) {
  switch (level) {
    case TrackingHealthLevel::kOk:
      return "ok";
    case TrackingHealthLevel::kRecovered:
      return "recovered";
    case TrackingHealthLevel::kLost:
      return "lost";
  }
  return "unknown";
}

TrackingHealthLabel trackingHealthLabel(TrackingHealthLevel level, double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) seconds = 0.0;
  TrackingHealthLabel label;
  label.level = level;
  char buf[64];
  switch (level) {
    case TrackingHealthLevel::kOk:
      label.text = "tracking: OK";
      label.r = 0.2f, label.g = 0.9f, label.b = 0.2f;
      break;
    case TrackingHealthLevel::kRecovered:
      std::snprintf(buf, sizeof(buf), "tracking: RECOVERED (gap %.1f s)", seconds);
      label.text = buf;
      label.r = 1.0f, label.g = 0.85f, label.b = 0.0f;
      break;
    case TrackingHealthLevel::kLost:
      std::snprintf(buf, sizeof(buf), "tracking: LOST %.1f s", seconds);
      label.text = buf;
      label.r = 1.0f, label.g = 0.15f, label.b = 0.15f;
      break;
  }
  return label;
}

TrackingHealthDisplay::TrackingHealthDisplay(double hold, double period)
    : hold_(hold), period_(period) {}

std::optional<TrackingHealthLabel> TrackingHealthDisplay::update(double stamp,
                                                                 const TrackingHealth& health,
                                                                 bool new_keyframe) {
  if (const auto gap = health.lastRecoveryGap()) recovered_at_ = stamp, recovered_gap_ = *gap;
  TrackingHealthLabel label;
  if (health.state() == TrackingState::kLost) {
    recovered_at_.reset();
    label = trackingHealthLabel(TrackingHealthLevel::kLost, health.timeSinceKeyframe());
  } else if (recovered_at_ && stamp - *recovered_at_ < hold_) {
    label = trackingHealthLabel(TrackingHealthLevel::kRecovered, recovered_gap_);
  } else {
    recovered_at_.reset();
    label = trackingHealthLabel(TrackingHealthLevel::kOk, 0.0);
  }
  const bool publish = !last_published_ || label.level != label_.level || new_keyframe ||
                       (label.level == TrackingHealthLevel::kLost &&
                        std::abs(stamp - *last_published_) >= period_ - 1e-6);
  label_ = label;
  if (!publish) return std::nullopt;
  last_published_ = stamp;
  return label;
}

}  // namespace osm_graph_slam
