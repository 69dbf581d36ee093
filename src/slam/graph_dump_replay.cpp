// Replaying a dump_graph directory into a GraphBackend (the reader is graph_dump.cpp).
#include <algorithm>
#include <map>

#include "osm_graph_slam/slam/graph_dump.h"

namespace osm_graph_slam {

BackendUpdateReport replayGraphDump(const GraphDump& dump, GraphBackend& backend,
                                    int optimize_every, bool final_full_batch) {
  if (dump.origin) backend.setOrigin(dump.origin->x(), dump.origin->y(), dump.origin->z());
  if (!dump.buildings.empty()) backend.addBuildings(dump.buildings, Eigen::Vector2d::Zero(), 1e9);
  std::multimap<uint64_t, const LoopClosureInput*> loops_by_from;
  for (const auto& l : dump.loops) loops_by_from.emplace(l.from_id, &l);
  BackendUpdateReport report, total;
  auto accumulate = [&](const BackendUpdateReport& r) {
    total.building_edges += r.building_edges;
    total.local_attempts += r.local_attempts;
    total.local_unseen += r.local_unseen;
    total.local_rejected += r.local_rejected;
    total.global_priors += r.global_priors;
    total.global_rejected += r.global_rejected;
    total.gnss_gated += r.gnss_gated;
    total.stage_ms += r.stage_ms;
    total.total_ms += r.total_ms;
  };
  int since_update = 0;
  for (const auto& kf : dump.keyframes) {
    backend.addKeyframe(kf);
    auto segs = dump.segments.find(kf.id);
    if (segs != dump.segments.end()) backend.addLineSegments(kf.id, segs->second);
    auto range = loops_by_from.equal_range(kf.id);
    for (auto it = range.first; it != range.second; ++it) backend.addLoopClosure(*it->second);
    if (++since_update >= std::max(1, optimize_every)) {
      accumulate(backend.update());
      since_update = 0;
    }
  }
  report = backend.update(final_full_batch);
  accumulate(report);
  // Counts and times summed over every update; the optimisation results are the last update's.
  report.building_edges = total.building_edges;
  report.local_attempts = total.local_attempts;
  report.local_unseen = total.local_unseen;
  report.local_rejected = total.local_rejected;
  report.global_priors = total.global_priors;
  report.global_rejected = total.global_rejected;
  report.gnss_gated = total.gnss_gated;
  report.stage_ms = total.stage_ms;
  report.total_ms = total.total_ms;
  return report;
}

}  // namespace osm_graph_slam
