#include "osm_graph_slam/eval/coverage.h"

#include <algorithm>
#include <vector>

namespace osm_graph_slam {
namespace {

/// Distance travelled along the ground truth between two stamps (linear between its poses).
class PathLength {
 public:
  explicit PathLength(const Trajectory& truth) {
    double s = 0.0;
    for (size_t i = 0; i < truth.size(); ++i) {
      if (i > 0) s += (truth[i].pose.translation() - truth[i - 1].pose.translation()).norm();
      stamps_.push_back(truth[i].stamp);
      lengths_.push_back(s);
    }
  }
  double between(double a, double b) const { return at(b) - at(a); }

 private:
  double at(double t) const {
    if (stamps_.empty()) return 0.0;
    if (t <= stamps_.front()) return lengths_.front();
    if (t >= stamps_.back()) return lengths_.back();
    const size_t j = std::upper_bound(stamps_.begin(), stamps_.end(), t) - stamps_.begin();
    const double w = (t - stamps_[j - 1]) / std::max(1e-12, stamps_[j] - stamps_[j - 1]);
    return lengths_[j - 1] + w * (lengths_[j] - lengths_[j - 1]);
  }
  std::vector<double> stamps_, lengths_;
};

}  // namespace

Coverage evaluateCoverage(const Trajectory& estimate, const Trajectory& ground_truth,
                          const CoverageOptions& options) {
  Coverage c;
  std::vector<double> est;
  for (const auto& p : estimate) est.push_back(p.stamp);
  std::sort(est.begin(), est.end());
  double start = 0.0, end = 0.0;
  bool have_span = false;
  for (const auto& p : ground_truth) {
    start = have_span ? std::min(start, p.stamp) : p.stamp;
    end = have_span ? std::max(end, p.stamp) : p.stamp;
    have_span = true;
  }
  if (options.input_span) {
    start = have_span ? std::min(start, options.input_span->first) : options.input_span->first;
    end = have_span ? std::max(end, options.input_span->second) : options.input_span->second;
    have_span = true;
  }
  if (!have_span && !est.empty()) start = est.front(), end = est.back(), have_span = true;
  c.ground_truth_start = start;
  c.ground_truth_end = end;
  c.ground_truth_span_s = end - start;
  if (est.empty()) {
    c.uncovered_s = c.longest_gap_s = c.ground_truth_span_s;
    c.longest_gap_start = start;
    c.longest_gap_m = PathLength(ground_truth).between(start, end);
    return c;
  }
  c.estimate_start = est.front();
  c.estimate_end = est.back();
  c.estimate_span_s = std::min(end, est.back()) - std::max(start, est.front());

  // Gaps: drive start -> first pose, between poses inside the drive, last pose -> drive end.
  std::vector<double> points = {start};
  for (double t : est)
    if (t > start && t < end) points.push_back(t);
  points.push_back(end);
  const PathLength path(ground_truth);
  for (size_t i = 1; i < points.size(); ++i) {
    const double gap = points[i] - points[i - 1];
    c.uncovered_s += std::max(0.0, gap - options.allowed_gap);
    if (gap > c.longest_gap_s) {
      c.longest_gap_s = gap;
      c.longest_gap_start = points[i - 1];
      c.longest_gap_m = path.between(points[i - 1], points[i]);
    }
  }
  c.fraction = c.ground_truth_span_s > 0
                   ? std::clamp(1.0 - c.uncovered_s / c.ground_truth_span_s, 0.0, 1.0)
                   : 1.0;
  return c;
}

}  // namespace osm_graph_slam
