#include "osm_graph_slam/odometry/fitness_gate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace osm_graph_slam {

FitnessGate::FitnessGate(double ratio, double floor, size_t window)
    : ratio_(ratio), floor_(floor), window_(std::max<size_t>(window, 1)) {}

double FitnessGate::limit() const {
  if (ratio_ <= 0.0 || recent_.size() < 3) return std::numeric_limits<double>::infinity();
  std::vector<double> v(recent_.begin(), recent_.end());
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return std::max(floor_, ratio_ * v[v.size() / 2]);
}

bool FitnessGate::accepts(double fitness) const {
  return std::isfinite(fitness) && fitness <= limit();
}

void FitnessGate::add(double fitness) {
  if (!std::isfinite(fitness)) return;
  recent_.push_back(fitness);
  if (recent_.size() > window_) recent_.pop_front();
}

}  // namespace osm_graph_slam
