#pragma once
// The localisation -> SLAM hand-over: a vehicle localises on a saved map (localization/
// localizer.h) and starts mapping only once it has left it. While the localiser tracks, the
// tracker's keyframes are held back, not mapped: the saved map already covers them. Once the
// localiser has not tracked for leave_after seconds (the scan is off the map, its registrations
// are refused, the filter is lost), the last `ties` keyframes it tracked and every keyframe after
// them are released, in order, to be mapped as a new session of the saved map (slam/map_resume.h)
// whose start the localiser's poses of those keyframes place. ROS-free: the SLAM pipeline and the
// graph_backend nodelet feed it, in whatever order the localiser's reports and the keyframes
// arrive.
#include <Eigen/Geometry>
#include <deque>
#include <optional>
#include <vector>

#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

struct LocalizationHandoverParams {
  /// [s] of scans the localiser did not track (off the map, registration refused, not
  /// localised) before mapping starts. Long enough that a few refused registrations on the map
  /// do not start a session (the localiser re-localises after 5 of 10); short enough that the
  /// keyframes held back since the last tracked one stay few (one every 2 m).
  double leave_after = 2.0;
  /// Tracked keyframes before the hand-over whose localised poses tie the new session to the
  /// saved map: more than one, so that one pose of a localiser already sliding off the map does
  /// not place the session alone (MapResume checks them against odometry).
  int ties = 3;
};

/// A keyframe released for mapping, with the localiser's pose of it (map frame) if it tracked it.
struct HandoverKeyframe {
  KeyframeInput keyframe;
  std::optional<Eigen::Isometry3d> localized;
};

class LocalizationHandover {
 public:
  explicit LocalizationHandover(const LocalizationHandoverParams& params) : params_(params) {}

  /// The localiser's result for the scan at `stamp` (in stamp order): tracking = corrected by
  /// the map (or re-localised) on that scan; pose = base_link in the map.
  void addLocalization(double stamp, bool tracking, const Eigen::Isometry3d& pose);
  /// A tracker keyframe (odometry frame, in stamp order), held until release() decides.
  void addKeyframe(const KeyframeInput& keyframe);
  /// The keyframes to map now, in order. Before the hand-over: none (a keyframe waits for the
  /// localiser's result of its scan). At it: the ties and the keyframes after them. After it:
  /// every keyframe as it comes.
  std::vector<HandoverKeyframe> release();

  /// What becomes of the tracker's keyframe `id` and of the inputs that name it (wall segments,
  /// floors, loops), which may arrive before or after it: they wait for the decision, go into
  /// the graph, or are dropped with a keyframe that was localised and never mapped.
  enum class Fate { kWaiting, kMapped, kLocalized };
  Fate fate(uint64_t id) const;

  bool mapping() const { return handover_stamp_.has_value(); }
  /// When mapping started: the first keyframe (or the localiser's latest scan) leave_after or
  /// more after the first scan it did not track.
  std::optional<double> handoverStamp() const { return handover_stamp_; }
  /// Keyframes the localiser tracked and that were not mapped (the saved map covers them).
  size_t keyframesLocalized() const { return keyframes_localized_; }

 private:
  struct Localization {
    double stamp;
    bool tracking;
    Eigen::Isometry3d pose;
  };
  /// The localiser's result for the scan at `stamp`, if it is still remembered.
  std::optional<Localization> localizationAt(double stamp) const;
  /// Keeps the held keyframes from the oldest of the last `ties` tracked ones on.
  void dropOlderThanTies();
  bool leftTheMap(double stamp) const;

  LocalizationHandoverParams params_;
  std::deque<Localization> localizations_;    ///< recent results (a few seconds of scans)
  std::deque<KeyframeInput> waiting_;         ///< keyframes whose scan the localiser has not done
  std::deque<HandoverKeyframe> held_;         ///< decided keyframes, not mapped yet
  std::optional<double> not_tracking_since_;  ///< first scan not tracked after the last tracked
  std::optional<double> handover_stamp_;
  std::optional<uint64_t> first_mapped_;   ///< the first keyframe released
  std::optional<uint64_t> last_localized_;  ///< the newest keyframe dropped as localised
  size_t keyframes_localized_ = 0;
};

}  // namespace osm_graph_slam
