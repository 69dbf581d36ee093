#include "osm_graph_slam/eval/loop_metrics.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>

namespace osm_graph_slam {
namespace {

/// The ground-truth pose nearest in time to stamp, if within max_dt.
std::optional<Eigen::Isometry3d> truthAt(const Trajectory& truth, double stamp, double max_dt) {
  auto it = std::lower_bound(truth.begin(), truth.end(), stamp,
                             [](const StampedPose& p, double t) { return p.stamp < t; });
  const StampedPose* best = nullptr;
  if (it != truth.end()) best = &*it;
  if (it != truth.begin() && (!best || stamp - std::prev(it)->stamp < best->stamp - stamp))
    best = &*std::prev(it);
  if (!best || std::abs(best->stamp - stamp) > max_dt) return std::nullopt;
  return best->pose;
}

}  // namespace

LoopEvaluation evaluateLoops(const std::vector<StampedLoopClosure>& loops,
                             const std::vector<double>& keyframe_stamps,
                             const Trajectory& ground_truth_in, const LoopEvalOptions& o) {
  Trajectory truth = ground_truth_in;
  std::sort(truth.begin(), truth.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.stamp < b.stamp; });
  LoopEvaluation e;
  e.accepted = loops.size();
  for (const auto& l : loops) {
    const auto from = truthAt(truth, l.from_stamp, o.max_time_difference);
    const auto to = truthAt(truth, l.to_stamp, o.max_time_difference);
    if (!from || !to) {
      ++e.unassociated;
      continue;
    }
    const Eigen::Isometry3d error = (to->inverse() * *from).inverse() * l.relative_pose;
    const double dt = error.translation().norm();
    const double dr = Eigen::AngleAxisd(error.linear()).angle() * 180.0 / M_PI;
    e.translation_errors.push_back(dt);
    e.rotation_errors_deg.push_back(dr);
    if (dt > o.false_translation || dr > o.false_rotation_deg) ++e.false_loops;
  }

  // Revisits among the run's keyframes, on their true positions and path lengths.
  std::vector<double> stamps = keyframe_stamps;
  std::sort(stamps.begin(), stamps.end());
  std::vector<Eigen::Vector3d> positions;
  std::vector<double> kept_stamps, path;
  for (double s : stamps) {
    const auto p = truthAt(truth, s, o.max_time_difference);
    if (!p) continue;
    const Eigen::Vector3d x = p->translation();
    path.push_back(path.empty() ? 0.0 : path.back() + (x - positions.back()).norm());
    positions.push_back(x);
    kept_stamps.push_back(s);
  }
  std::set<double> loop_starts;
  for (const auto& l : loops) loop_starts.insert(l.from_stamp);
  auto hasLoop = [&](double stamp) {
    auto it = loop_starts.lower_bound(stamp - o.max_time_difference);
    return it != loop_starts.end() && *it <= stamp + o.max_time_difference;
  };
  bool in_event = false, event_closed = false;
  for (size_t j = 0; j < positions.size(); ++j) {
    bool revisit = false;
    for (size_t i = 0; i < j && !revisit; ++i)
      revisit = path[j] - path[i] >= o.min_path_gap &&
                (positions[j] - positions[i]).norm() <= o.revisit_radius;
    if (revisit) {
      ++e.revisit_keyframes;
      if (!in_event) ++e.revisit_events, event_closed = false;
      if (!event_closed && hasLoop(kept_stamps[j])) ++e.events_closed, event_closed = true;
    }
    in_event = revisit;
  }
  e.recall = e.revisit_events ? double(e.events_closed) / e.revisit_events : 1.0;
  return e;
}

}  // namespace osm_graph_slam
