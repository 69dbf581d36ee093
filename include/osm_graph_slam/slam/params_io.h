#pragma once
// Reading the back-end's parameters (and the line matcher's) from any ParamReader.
#include <string>

#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/lines/params_io.h"  // readParams(LineMatcherParams), kept for callers
#include "osm_graph_slam/slam/backend_params.h"

namespace osm_graph_slam {

/// The back-end's keys at the top level, the matcher's below "line_matcher/", the optimizer's
/// below "graph_optimizer/". Returns false with a reason for an invalid value (e.g. an unknown
/// mode or kernel, a deviation out of range), which keeps its default; valid fields are still
/// read. The slices without checks beyond their declared choices are read by
/// readDeclaredParams() (common/param_declaration.h).
bool readParams(const ParamReader& reader, GraphBackendParams& params, std::string* error);
/// With the range checks of the information model and the odometry scale.
bool readParams(const ParamReader& reader, OdometryEdgeParams& params, std::string* error);
/// With the optimizer's keys below "graph_optimizer/".
bool readParams(const ParamReader& reader, OptimizationScheduleParams& params, std::string* error);
bool readParams(const ParamReader& reader, OptimizerOptions& params, std::string* error);

}  // namespace osm_graph_slam
