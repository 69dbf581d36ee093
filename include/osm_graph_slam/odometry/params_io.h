#pragma once
// Reading KeyframeTrackerParams from any ParamReader with the keys of config/scan_matching.yaml:
// the tracker's fields and its registration's fields side by side at the top level, the
// registration back-end as "registration_method".
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, KeyframeTrackerParams& params);

}  // namespace osm_graph_slam
