#pragma once
// Reading the back-end's parameters (and the line matcher's) from any ParamReader.
#include <string>

#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/lines/params_io.h"  // readParams(LineMatcherParams), kept for callers
#include "osm_graph_slam/slam/backend_params.h"

namespace osm_graph_slam {

/// The back-end's keys at the top level, the matcher's below "line_matcher/". Returns false with
/// a reason for an invalid value (e.g. an unknown mode); valid fields are still read.
bool readParams(const ParamReader& reader, GraphBackendParams& params, std::string* error);
bool readParams(const ParamReader& reader, OptimizerOptions& params, std::string* error);

}  // namespace osm_graph_slam
