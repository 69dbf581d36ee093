#pragma once
// The data behind the evaluation plots, as JSON for scripts/plot_evaluation.py.
#include <string>

#include "osm_graph_slam/eval/slam_evaluation.h"

namespace osm_graph_slam {

/// Positions, per-pose ATE along the path and ENU outlines of every building set.
std::string plotDataJson(const SlamEvaluationInput& input, const SlamEvaluation& evaluation);

}  // namespace osm_graph_slam
