#include "osm_graph_slam/eval/slam_evaluation.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

namespace osm_graph_slam {
namespace {

using nlohmann::json;

json statsJson(const ErrorStats& s) {
  return {{"count", s.count}, {"mean", s.mean},     {"std", s.std},
          {"rmse", s.rmse},   {"median", s.median}, {"max", s.max}};
}

json trajectoryJson(const TrajectoryErrors& e) {
  return {{"associated", e.associated},
          {"ate_m", statsJson(e.ate)},
          {"rpe_trans_m", statsJson(e.rpe_trans)},
          {"rpe_rot_rad", statsJson(e.rpe_rot)},
          {"height_drift_m", statsJson(e.height_drift)},
          {"tilt_rad", statsJson(e.tilt)},
          {"kitti_segments", e.kitti_segments},
          {"kitti_trans_percent", e.kitti_trans_percent},
          {"kitti_rot_deg_per_100m", e.kitti_rot_deg_per_100m}};
}

json buildingsJson(const BuildingSetEvaluation& b) {
  return {{"matched", b.errors.matched},
          {"vertex_mismatch", b.errors.vertex_mismatch},
          {"mean_corner_error_m", b.errors.mean_corner_error},
          {"max_corner_error_m", b.errors.max_corner_error},
          {"mean_heading_error_deg", b.errors.mean_heading_error_deg},
          {"mean_vertex_error_m", b.errors.mean_vertex_error},
          {"common_offset_m", b.errors.common_offset},
          {"mean_corner_error_shape_m", b.errors.mean_corner_error_shape},
          {"overlapping_pairs", b.overlapping_pairs}};
}

BuildingSetEvaluation evaluateSet(const std::vector<Building>& set,
                                  const std::vector<Building>& truth) {
  BuildingSetEvaluation out;
  out.errors = evaluateBuildings(set, truth);
  out.overlapping_pairs = findOverlappingBuildings(set).size();
  return out;
}

/// Buildings of `set` whose (id, part) is in `reference`.
std::vector<Building> sameIds(const std::vector<Building>& set,
                              const std::vector<Building>& reference) {
  std::set<std::pair<int64_t, int>> ids;
  for (const auto& b : reference) ids.insert({b.id, b.part});
  std::vector<Building> out;
  for (const auto& b : set)
    if (ids.count({b.id, b.part})) out.push_back(b);
  return out;
}

/// Buildings of `set` whose id is among the observed corrected buildings.
std::vector<Building> observedSubset(const std::vector<Building>& set,
                                     const std::vector<Building>& corrected) {
  std::vector<Building> observed;
  for (const auto& b : corrected) {
    auto it = b.tags.find(kObservationsTag);
    if (it != b.tags.end() && std::atoi(it->second.c_str()) > 0) observed.push_back(b);
  }
  return sameIds(set, observed);
}

std::string fmt(const char* format, double a, double b) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, a, b);
  return buf;
}

void trajectoryRow(std::ostringstream& os, const std::string& label, const TrajectoryErrors& e) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%-12s %6zu  %-17s %7.3f %7.3f  %-17s %-19s %7.2f\n",
                label.c_str(), e.associated, fmt("%.3f ± %.3f", e.ate.mean, e.ate.std).c_str(),
                e.ate.rmse, e.ate.max,
                fmt("%.3f ± %.3f", e.rpe_trans.mean, e.rpe_trans.std).c_str(),
                fmt("%.4f ± %.4f", e.rpe_rot.mean, e.rpe_rot.std).c_str(), e.kitti_trans_percent);
  os << buf;
}

void buildingRow(std::ostringstream& os, const std::string& label, const BuildingSetEvaluation& b) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%-12s %7zu  %9.3f %9.3f %11.2f %9zu\n", label.c_str(),
                b.errors.matched, b.errors.mean_corner_error, b.errors.max_corner_error,
                b.errors.mean_heading_error_deg, b.overlapping_pairs);
  os << buf;
}

}  // namespace

SlamEvaluation evaluateSlam(const SlamEvaluationInput& input) {
  SlamEvaluation out;
  out.slam = evaluateTrajectory(input.estimate, input.ground_truth, input.options);
  out.coverage = evaluateCoverage(input.estimate, input.ground_truth, input.coverage);
  out.untracked_scans = input.untracked_scans;
  out.lost_events = input.lost_events;
  if (input.loops) {
    std::vector<double> keyframes;
    for (const auto& p : input.estimate) keyframes.push_back(p.stamp);
    out.loops = evaluateLoops(*input.loops, keyframes, input.ground_truth, input.loop_options);
  }
  out.baseline_label = input.baseline_label;
  if (input.baseline) {
    out.baseline = evaluateTrajectory(*input.baseline, input.ground_truth, input.options);
    if (out.baseline->ate.mean > 0.0)
      out.ate_change_vs_baseline = out.slam.ate.mean / out.baseline->ate.mean - 1.0;
  }
  if (!input.buildings_true.empty()) {
    // The prior on the buildings the run had (the same ids as the corrected set), if given.
    if (!input.buildings_prior.empty())
      out.prior = evaluateSet(input.buildings_corrected.empty()
                                  ? input.buildings_prior
                                  : sameIds(input.buildings_prior, input.buildings_corrected),
                              input.buildings_true);
    if (!input.buildings_corrected.empty())
      out.corrected = evaluateSet(input.buildings_corrected, input.buildings_true);
    const auto seen = observedSubset(input.buildings_corrected, input.buildings_corrected);
    if (!seen.empty()) {
      out.corrected_observed = evaluateSet(seen, input.buildings_true);
      const auto seen_prior = observedSubset(input.buildings_prior, input.buildings_corrected);
      if (!seen_prior.empty()) out.prior_observed = evaluateSet(seen_prior, input.buildings_true);
    }
  }
  return out;
}

namespace {

json coverageJson(const SlamEvaluation& e) {
  const Coverage& c = e.coverage;
  json j = {{"ground_truth_span_s", c.ground_truth_span_s},
            {"estimate_span_s", c.estimate_span_s},
            {"fraction", c.fraction},
            {"uncovered_s", c.uncovered_s},
            {"longest_gap_s", c.longest_gap_s},
            {"longest_gap_m", c.longest_gap_m},
            {"longest_gap_start", c.longest_gap_start},
            {"untracked_scans", nullptr},
            {"lost_events", nullptr}};
  if (e.untracked_scans) j["untracked_scans"] = *e.untracked_scans;
  if (e.lost_events) j["lost_events"] = *e.lost_events;
  return j;
}

json loopsJson(const LoopEvaluation& l) {
  return {{"accepted", l.accepted},
          {"false", l.false_loops},
          {"unassociated", l.unassociated},
          {"revisits", l.revisit_events},
          {"revisit_keyframes", l.revisit_keyframes},
          {"revisits_closed", l.events_closed},
          {"recall", l.recall},
          {"max_translation_error_m",
           l.translation_errors.empty()
               ? 0.0
               : *std::max_element(l.translation_errors.begin(), l.translation_errors.end())}};
}

}  // namespace

std::string evaluationToJson(const SlamEvaluation& e) {
  json doc = {{"slam", trajectoryJson(e.slam)}, {"coverage", coverageJson(e)}};
  if (e.loops) doc["loops"] = loopsJson(*e.loops);
  if (e.baseline) doc[e.baseline_label] = trajectoryJson(*e.baseline);
  if (e.ate_change_vs_baseline)
    doc["ate_change_vs_" + e.baseline_label] = *e.ate_change_vs_baseline;
  if (e.prior) doc["buildings_prior"] = buildingsJson(*e.prior);
  if (e.corrected) doc["buildings_corrected"] = buildingsJson(*e.corrected);
  if (e.prior_observed) doc["buildings_prior_observed"] = buildingsJson(*e.prior_observed);
  if (e.corrected_observed)
    doc["buildings_corrected_observed"] = buildingsJson(*e.corrected_observed);
  return doc.dump(2);
}

namespace {

void coverageRows(std::ostringstream& os, const SlamEvaluation& e) {
  const Coverage& c = e.coverage;
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "coverage: %.1f %% of %.1f s (estimate %.1f s), longest gap %.1f s / %.1f m at "
                "%.1f s",
                100.0 * c.fraction, c.ground_truth_span_s, c.estimate_span_s, c.longest_gap_s,
                c.longest_gap_m, c.longest_gap_start - c.ground_truth_start);
  os << buf;
  if (e.untracked_scans) os << ", " << *e.untracked_scans << " untracked scans";
  if (e.lost_events) os << ", " << *e.lost_events << " lost track(s)";
  os << "\n";
  if (c.fraction < kCoverageWarning) {
    std::snprintf(buf, sizeof(buf),
                  "WARNING: the estimate covers only %.1f %% of the drive: the errors above "
                  "describe the covered part only\n",
                  100.0 * c.fraction);
    os << buf;
  }
  if (e.loops) {
    const LoopEvaluation& l = *e.loops;
    std::snprintf(buf, sizeof(buf),
                  "loops: %zu accepted, %zu false (> 1 m / 2 deg); %zu of %zu ground-truth "
                  "revisits closed (recall %.0f %%)\n",
                  l.accepted, l.false_loops, l.events_closed, l.revisit_events, 100.0 * l.recall);
    os << buf;
  }
}

}  // namespace

std::string evaluationToTable(const SlamEvaluation& e) {
  std::ostringstream os;
  os << "trajectory   poses   ATE mean ± std [m] RMSE    max   t_RPE [m]         r_RPE [rad]"
        "         KITTI [%]\n";
  trajectoryRow(os, "slam", e.slam);
  if (e.baseline) trajectoryRow(os, e.baseline_label, *e.baseline);
  if (e.ate_change_vs_baseline) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "ATE change vs %s: %+.1f %%\n", e.baseline_label.c_str(),
                  100.0 * *e.ate_change_vs_baseline);
    os << buf;
  }
  coverageRows(os, e);
  if (e.prior || e.corrected) {
    os << "\nbuildings   matched  corner[m]  max[m]  heading[deg]  overlaps\n";
    if (e.prior) buildingRow(os, "prior (OSM)", *e.prior);  // same ids as corrected
    if (e.corrected) buildingRow(os, "corrected", *e.corrected);
    if (e.prior_observed) buildingRow(os, "prior, seen", *e.prior_observed);
    if (e.corrected_observed) buildingRow(os, "corr., seen", *e.corrected_observed);
  }
  return os.str();
}

}  // namespace osm_graph_slam
