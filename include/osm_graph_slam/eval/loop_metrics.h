#pragma once
// Loop closures against the ground truth: which accepted loops are false, and how many of the
// places the drive really revisited got a loop (recall). A revisit is a keyframe within
// revisit_radius of a keyframe at least min_path_gap earlier along the path; consecutive revisit
// keyframes form one revisit event, closed when an accepted loop starts at one of its keyframes.
#include <vector>

#include "osm_graph_slam/io/loop_closure_file.h"
#include "osm_graph_slam/io/trajectory_io.h"

namespace osm_graph_slam {

struct LoopEvalOptions {
  double revisit_radius = 5.0;        ///< [m]
  double min_path_gap = 25.0;         ///< [m] along the ground-truth path
  double false_translation = 1.0;     ///< [m] a loop whose error exceeds this is false
  double false_rotation_deg = 2.0;    ///< [deg] ... or this
  double max_time_difference = 0.02;  ///< [s] stamp association with the ground truth
};

struct LoopEvaluation {
  size_t accepted = 0;      ///< loops in the file
  size_t unassociated = 0;  ///< loops whose stamps have no ground-truth pose (not judged)
  size_t false_loops = 0;
  size_t revisit_keyframes = 0, revisit_events = 0, events_closed = 0;
  double recall = 0.0;  ///< events_closed / revisit_events (1 when there is no revisit)
  std::vector<double> translation_errors, rotation_errors_deg;  ///< per judged loop
};

/// keyframe_stamps: the run's keyframes (e.g. the stamps of its trajectory).
LoopEvaluation evaluateLoops(const std::vector<StampedLoopClosure>& loops,
                             const std::vector<double>& keyframe_stamps,
                             const Trajectory& ground_truth, const LoopEvalOptions& options = {});

}  // namespace osm_graph_slam
