#pragma once
// Adaptive fitness gate: a match is plausible only if its fitness (mean squared inlier distance)
// is within `ratio` times the median of the recently accepted ones. A fixed max_fitness cannot
// tell a false match from a true one: on real KITTI scans true matches lie between 0.06 and
// 0.22 m^2 (median 0.12, kitti_raw_0005), on simulated scans near 0.01, while a registration that
// converged into the wrong basin scores 0.8-0.9 m^2 with 2 m correspondences — under the fixed
// 1.0 m^2 limit, and accepted, after which every later scan tracks a wrong keyframe.
#include <cstddef>
#include <deque>

namespace osm_graph_slam {

class FitnessGate {
 public:
  /// ratio <= 0 disables the gate. floor: [m^2] the limit never goes below it (noise-free
  /// scenes have a median near zero).
  FitnessGate(double ratio, double floor, size_t window = 15);
  /// True while fewer than 3 fitness values were seen, or fitness <= limit().
  bool accepts(double fitness) const;
  double limit() const;
  void add(double fitness);
  void clear() { recent_.clear(); }

 private:
  double ratio_, floor_;
  size_t window_;
  std::deque<double> recent_;
};

}  // namespace osm_graph_slam
