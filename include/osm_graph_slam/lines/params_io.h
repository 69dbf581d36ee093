#pragma once
// Reading the lines stage's parameters from any ParamReader. Keys are the field names: the
// "segments/" block of config/line_extraction.yaml and the "line_matcher/" block of
// config/graph_backend.yaml (the caller passes a PrefixedParamReader).
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, LineSegmentExtractorParams& params);
void readParams(const ParamReader& reader, LineMatcherParams& params);

}  // namespace osm_graph_slam
