#pragma once
// When the graph back-end's optimisation thread runs next (graph_backend nodelet).

#include <algorithm>

namespace osm_graph_slam {

/// Seconds to wait after an update that took `busy_s`: the period, stretched so the optimisation
/// uses at most `max_duty_cycle` of a core. The full-batch update grows with the graph (≈4 s at
/// 4,500 keyframes here); run back to back it took a whole core of a 2-core machine and starved
/// the other nodelets (doc/reliability.md, soak). max_duty_cycle ≥ 1 (or ≤ 0): the period only.
inline double optimizationWait(double period_s, double busy_s, double max_duty_cycle) {
  if (max_duty_cycle <= 0.0 || max_duty_cycle >= 1.0) return period_s;
  return std::max(period_s, busy_s * (1.0 - max_duty_cycle) / max_duty_cycle);
}

}  // namespace osm_graph_slam
