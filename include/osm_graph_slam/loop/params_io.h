#pragma once
// Reading the loop stage's parameters from any ParamReader with the keys of
// config/loop_detection.yaml: the detector's fields at the top level, the descriptor's under
// "scan_context/" and the fine registration's under "registration/". The nodelet-only "mode"
// (odometry | place_recognition) is not part of LoopDetectorParams and is not read here.
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/loop/scan_context.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, ScanContextParams& params);
void readParams(const ParamReader& reader, LoopDetectorParams& params);

}  // namespace osm_graph_slam
