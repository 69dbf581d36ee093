#pragma once
// How much of a drive the estimate covers: a run that stopped making keyframes half-way must not
// score well on the poses it has. Compared in time against the ground truth (and the span of the
// scans the run read, when its report says so).
#include <optional>
#include <utility>

#include "osm_graph_slam/io/trajectory_io.h"

namespace osm_graph_slam {

struct CoverageOptions {
  /// [s] a span without estimated poses up to this long is normal (keyframes are made every few
  /// seconds at most); only the excess counts as uncovered. Applies to the start and end too.
  double allowed_gap = 3.0;
  /// [first, last] stamp of the scans the run read, if known: widens the ground-truth span.
  std::optional<std::pair<double, double>> input_span;
};

struct Coverage {
  double ground_truth_start = 0, ground_truth_end = 0;  ///< [s] the drive (widened by input_span)
  double estimate_start = 0, estimate_end = 0;          ///< [s]
  double ground_truth_span_s = 0, estimate_span_s = 0;  ///< [s]
  double uncovered_s = 0;    ///< [s] the gaps' excess over allowed_gap, start and end included
  double fraction = 0;       ///< 1 - uncovered / ground-truth span (0 when no estimate)
  double longest_gap_s = 0;  ///< [s] between consecutive estimated poses, or to the drive's ends
  double longest_gap_m = 0;  ///< [m] travelled (ground truth) during that gap
  double longest_gap_start = 0;  ///< [s] stamp where it begins
};

Coverage evaluateCoverage(const Trajectory& estimate, const Trajectory& ground_truth,
                          const CoverageOptions& options = {});

}  // namespace osm_graph_slam
