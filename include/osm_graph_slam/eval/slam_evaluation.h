#pragma once
// One evaluation of a SLAM run: trajectory errors (SLAM and, optionally, odometry-only) and
// building errors (prior map and corrected map against the truth), as a table or JSON.
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/eval/coverage.h"
#include "osm_graph_slam/eval/loop_metrics.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"

namespace osm_graph_slam {

struct SlamEvaluationInput {
  Trajectory estimate;
  Trajectory ground_truth;
  std::optional<Trajectory> baseline;  ///< e.g. odometry (+ loops) only, same ground truth
  std::string baseline_label = "odometry";
  std::vector<Building> buildings_true, buildings_prior, buildings_corrected;  ///< ENU filled
  TrajectoryEvalOptions options;
  CoverageOptions coverage;  ///< input_span from the run's report, when given
  /// From the run's report (offline_slam timing.json "tracking"), when given.
  std::optional<size_t> untracked_scans, lost_events;
  std::optional<std::vector<StampedLoopClosure>> loops;  ///< the run's accepted loops
  LoopEvalOptions loop_options;
};

struct BuildingSetEvaluation {
  BuildingErrors errors;
  size_t overlapping_pairs = 0;
};

struct SlamEvaluation {
  TrajectoryErrors slam;
  std::optional<TrajectoryErrors> baseline;
  std::string baseline_label;
  std::optional<BuildingSetEvaluation> prior, corrected;
  /// The same two restricted to the buildings SLAM observed (corrected buildings tagged with
  /// kObservationsTag > 0): the ones it could correct, compared on the same ids.
  std::optional<BuildingSetEvaluation> prior_observed, corrected_observed;
  /// Relative ATE change of SLAM against the baseline (negative = better), when both exist.
  std::optional<double> ate_change_vs_baseline;
  Coverage coverage;  ///< of the SLAM estimate
  std::optional<size_t> untracked_scans, lost_events;
  std::optional<LoopEvaluation> loops;
};

/// Below this coverage fraction the table prints a warning line.
inline constexpr double kCoverageWarning = 0.99;

SlamEvaluation evaluateSlam(const SlamEvaluationInput& input);
std::string evaluationToJson(const SlamEvaluation& evaluation);
std::string evaluationToTable(const SlamEvaluation& evaluation);

}  // namespace osm_graph_slam
