#pragma once
// Shared set-ups of the back-end's evidence tests (GNSS, INS): a straight drive without OSM.
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

/// Back-end parameters without OSM, with a known initial heading (ENU yaw 0).
inline GraphBackendParams noOsmKnownHeading() {
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = true;
  params.initial_yaw = 0.0;
  return params;
}

/// Keyframe i of a straight drive along x, 2 m and 1 s apart, with exact odometry.
inline KeyframeInput straightKeyframe(uint64_t i) {
  KeyframeInput kf;
  kf.id = i;
  kf.stamp = 1.0 + i;
  kf.odom_pose.translation().x() = 2.0 * i;
  kf.accum_distance = 2.0 * i;
  kf.odom_fitness = 0.05;
  return kf;
}

}  // namespace osm_graph_slam
