#pragma once
// When the graph back-end's optimisation thread runs next (graph_backend nodelet).

#include <algorithm>
#include <cstdint>

namespace osm_graph_slam {

/// Seconds to wait after an update that took `busy_s`: the period, stretched so the optimisation
/// uses at most `max_duty_cycle` of a core. The full-batch update grows with the graph (≈4 s at
/// 4,500 keyframes here); run back to back it took a whole core of a 2-core machine and starved
/// the other nodelets (doc/reliability.md, soak). max_duty_cycle ≥ 1 (or ≤ 0): the period only.
inline double optimizationWait(double period_s, double busy_s, double max_duty_cycle) {
  if (max_duty_cycle <= 0.0 || max_duty_cycle >= 1.0) return period_s;
  return std::max(period_s, busy_s * (1.0 - max_duty_cycle) / max_duty_cycle);
}

/// Keyframe-driven schedule (optimize_every_keyframes > 0): the back-end optimises once `every`
/// keyframes arrived since its last update, as offline_slam does, so a replayed bag is optimised
/// at the same keyframes whatever the machine's load (a wall-clock period optimises at keyframes
/// that depend on how fast the machine replays). Keyframes that stopped arriving (the bag ended,
/// the vehicle stands) are optimised once none came for `idle_period_s`.
inline bool keyframeUpdateDue(uint64_t received, uint64_t at_last_update, int every, double idle_s,
                              double idle_period_s) {
  if (received <= at_last_update) return false;
  return received - at_last_update >= static_cast<uint64_t>(std::max(every, 1)) ||
         idle_s >= idle_period_s;
}

}  // namespace osm_graph_slam
