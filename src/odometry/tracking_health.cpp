#include "osm_graph_slam/odometry/tracking_health.h"

#include <algorithm>
#include <cstdio>

namespace osm_graph_slam {

const char* toString(TrackingState state) {
  return state == TrackingState::kOk ? "ok" : "lost";
}

TrackingHealth::TrackingHealth(double lost_after) : lost_after_(lost_after) {}

double TrackingHealth::timeSinceKeyframe() const {
  return last_keyframe_stamp_ ? std::max(0.0, stats_.last_stamp - *last_keyframe_stamp_) : 0.0;
}

TrackingStats TrackingHealth::stats() const {
  TrackingStats s = stats_;
  s.longest_no_keyframe_s = std::max(s.longest_no_keyframe_s, timeSinceKeyframe());
  return s;
}

std::optional<TrackingEvent> TrackingHealth::update(double stamp, const TrackResult& result) {
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
  }
  ++stats_.scans;
  if (stats_.scans == 1) stats_.first_stamp = stamp;
  stats_.last_stamp = std::max(stats_.last_stamp, stamp);
  if (!result.new_keyframe) return checkGap(stamp, result.message);

  ++stats_.keyframes;
  std::optional<TrackingEvent> event;
  if (last_keyframe_stamp_) {
    const double gap = stamp - *last_keyframe_stamp_;
    stats_.longest_no_keyframe_s = std::max(stats_.longest_no_keyframe_s, gap);
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

std::optional<TrackingEvent> TrackingHealth::updateRejected(double stamp,
                                                            const std::string& reason) {
  ++stats_.scans;
  ++stats_.rejected_scans;
  if (stats_.scans == 1) stats_.first_stamp = stamp;
  stats_.last_stamp = std::max(stats_.last_stamp, stamp);
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

}  // namespace osm_graph_slam
