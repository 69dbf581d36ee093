#pragma once
// A plain Ceres pose-graph formulation written from the Ceres documentation's pose-graph examples
// (2D: x, y and a yaw on an angle manifold as three scalar blocks per pose; 3D: a position block
// and an Eigen quaternion block per pose; automatic differentiation). It is the baseline that
// graph_benchmark and the dataset tests compare PoseGraph::optimize with.
//
// The documentation examples express the residual in a different frame (translation not rotated
// into the measurement frame, 3D rotation error 2·vec(Z·Q⁻¹)); the information matrix is mapped
// accordingly (Ω' = M⁻ᵀ Ω M⁻¹ for the linear map e' = M e between the two error vectors), so the
// objective is exactly the g2o χ² and the final χ² of both formulations are comparable.
#include <string>

#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam {

struct ReferenceSolveResult {
  bool ok = false;
  std::string message;
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
  int iterations = 0;
  double time_ms = 0.0;  ///< problem set-up + solve
  std::string termination;
  std::string report;  ///< Ceres' full report (only with OptimizerOptions::verbose)
};

/// Solves every SE2/SE3 relative-pose edge of `graph` (other edge types: error). Fixed vertices
/// stay constant. Uses the same Ceres solver settings as `options`. If `solution` is given it
/// receives a copy of `graph` holding the optimised estimates.
ReferenceSolveResult solveReferenceFormulation(const PoseGraph& graph,
                                               const OptimizerOptions& options,
                                               PoseGraph* solution = nullptr);

}  // namespace osm_graph_slam
