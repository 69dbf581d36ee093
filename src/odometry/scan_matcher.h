#pragma once
// What KeyframeTracker registers each scan against, one implementation per `tracker` choice:
// GICP on the prefiltered scan against the graph keyframe, or the multi-cue photometric
// registration of the full-resolution scan against tracker keyframes (doc/multi_cue.md). Private
// to src/odometry: the tracker's header stays free of either back-end.
#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

/// One scan for a matcher: the prefiltered cloud in base_link and, for the multi-cue matcher,
/// the full-resolution scan in the LiDAR's frame (null: the matcher uses `cloud` moved there).
struct MatcherScan {
  PointCloudConstPtr cloud;
  PointCloudConstPtr sensor_scan;
  Eigen::Isometry3d sensor_to_base = Eigen::Isometry3d::Identity();
};

class ScanMatcher {
 public:
  virtual ~ScanMatcher() = default;
  /// Later scans are registered against this one. Throws when the scan cannot serve (e.g. a
  /// cloud GICP cannot index); the tracker reports that as a rejected cloud.
  virtual void setReference(const MatcherScan& scan) = 0;
  /// The scan's base_link pose in the reference's base_link (p_reference = transform * p_scan)
  /// from `guess`. Never throws: converged = false and a message instead.
  virtual RegistrationResult align(const MatcherScan& scan, const Eigen::Isometry3d& guess) = 0;
  /// Whether a scan matched at `relative` to the reference should become the reference before
  /// the next graph keyframe (the multi-cue tracker's own keyframes).
  virtual bool wantsReference(const Eigen::Isometry3d& relative) const = 0;
  /// True when align()'s fitness and Hessian describe the graph's odometry edge (GICP against
  /// the graph keyframe), so that the back-end may weigh the edge by them.
  virtual bool registrationIsEdge() const = 0;
  /// A remark to log once per run, handed out once ("" when none is new).
  virtual std::string takeNotice() { return {}; }
};

/// The matcher of params.tracker; throws std::invalid_argument for an unknown choice.
std::unique_ptr<ScanMatcher> createScanMatcher(const KeyframeTrackerParams& params);

}  // namespace osm_graph_slam
