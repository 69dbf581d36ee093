#pragma once
// Tracking health of the scan-matching odometry: counts what the tracker did with every scan and
// notices when no keyframe was made for too long (the track is lost), so that a failure that
// loses part of a drive is counted and logged once instead of passing silently. ROS-free; the
// pipeline and the scan_matching nodelet feed it the tracker's results.
#include <cstddef>
#include <optional>
#include <string>

#include "osm_graph_slam/odometry/keyframe_tracker.h"

namespace osm_graph_slam {

enum class TrackingState { kOk, kLost };
const char* toString(TrackingState state);

struct TrackingStats {
  size_t scans = 0;           ///< every scan offered (including rejected ones)
  size_t matched = 0;         ///< registrations accepted
  size_t failed_matches = 0;  ///< registrations failed or rejected (prediction kept)
  size_t rejected_scans = 0;  ///< empty/too small clouds and out-of-order stamps
  size_t keyframes = 0;
  size_t reanchors = 0;         ///< keyframes re-anchored on a guess after failed matches
  size_t restarts = 0;          ///< tracking restarts after the time jumped back (looped bag)
  size_t lost_events = 0;       ///< times the track was declared lost
  size_t scans_while_lost = 0;  ///< scans that arrived while the track was lost
  double first_stamp = 0.0, last_stamp = 0.0;  ///< [s] of the scans offered (0 before any)
  double longest_no_keyframe_s = 0.0;          ///< longest span without a keyframe, open end too
};

/// One line to log when the state changed (lost or recovered), with the scan number and stamp.
struct TrackingEvent {
  TrackingState state = TrackingState::kOk;
  std::string message;
};

class TrackingHealth {
 public:
  /// lost_after: [s] without a keyframe after which the track counts as lost.
  explicit TrackingHealth(double lost_after = 3.0);

  /// Accounts the tracker's result for a scan taken at stamp [s].
  std::optional<TrackingEvent> update(double stamp, const TrackResult& result);
  /// A scan that never reached the tracker (no cloud, rejected by the prefilter).
  std::optional<TrackingEvent> updateRejected(double stamp, const std::string& reason);

  TrackingState state() const { return state_; }
  /// [s] without a keyframe that the last scan's keyframe closed, when that keyframe was
  /// re-anchored on a guess or ended a lost span (a recovery); nullopt otherwise.
  std::optional<double> lastRecoveryGap() const { return recovery_gap_; }
  /// [s] since the last keyframe at the last scan (0 before the first keyframe).
  double timeSinceKeyframe() const;
  TrackingStats stats() const;

 private:
  std::optional<TrackingEvent> checkGap(double stamp, const std::string& reason);
  /// The tracker restarted after the time jumped back: one event to log, counted.
  std::optional<TrackingEvent> restarted(double stamp, const TrackResult& result);

  double lost_after_;
  TrackingStats stats_;
  TrackingState state_ = TrackingState::kOk;
  std::optional<double> last_keyframe_stamp_;
  /// [s] the latest scan stamp since the last restart (the time since a keyframe runs from it).
  double latest_stamp_ = 0.0;
  size_t failures_in_row_ = 0;
  std::optional<double> recovery_gap_;
};

/// What the rviz view shows of the tracking health (the scan_matching nodelet's
/// tracking_health_marker): three levels, a short text and a colour.
enum class TrackingHealthLevel { kOk, kRecovered, kLost };
const char* toString(TrackingHealthLevel level);

struct TrackingHealthLabel {
  TrackingHealthLevel level = TrackingHealthLevel::kOk;
  std::string text;
  float r = 0.f, g = 0.f, b = 0.f;  ///< colour in [0, 1]
};

/// "tracking: OK" (green), "tracking: RECOVERED (gap 1.2 s)" (yellow), "tracking: LOST 4.0 s"
/// (red). seconds: the span without a keyframe that the recovery closed, or how long the lost
/// track has been without one; ignored for kOk. Negative or non-finite seconds print as 0.0.
TrackingHealthLabel trackingHealthLabel(TrackingHealthLevel level, double seconds);

/// Decides what the label shows and when it is worth publishing, scan by scan: a recovery stays
/// on screen for `hold` s of stamps (it would flash for one scan otherwise), a lost track's
/// counter is refreshed every `period` s, and otherwise the label is published only with a new
/// keyframe or when its level changes.
class TrackingHealthDisplay {
 public:
  explicit TrackingHealthDisplay(double hold = 5.0, double period = 1.0);

  /// Call after TrackingHealth::update / updateRejected for the scan at stamp [s]; returns the
  /// label to publish, or nullopt when the one on screen is still right.
  std::optional<TrackingHealthLabel> update(double stamp, const TrackingHealth& health,
                                            bool new_keyframe);
  /// The label of the last update (kOk before any).
  const TrackingHealthLabel& label() const { return label_; }

 private:
  double hold_, period_;
  TrackingHealthLabel label_ = trackingHealthLabel(TrackingHealthLevel::kOk, 0.0);
  std::optional<double> last_published_;
  std::optional<double> recovered_at_;
  double recovered_gap_ = 0.0;
};

}  // namespace osm_graph_slam
