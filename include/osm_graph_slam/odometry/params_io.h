#pragma once
// Reading KeyframeTrackerParams from any ParamReader with the keys of config/scan_matching.yaml:
// the tracker's fields and its registration's fields side by side at the top level, the
// registration back-end as "registration_method", the multi-cue tracker's as "multi_cue_*". The
// choices (tracker, guess) are checked by KeyframeTrackerParams::validate().
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, KeyframeTrackerParams& params);

}  // namespace osm_graph_slam
