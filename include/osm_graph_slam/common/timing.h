#pragma once
// Wall time of a stage, for the per-stage milliseconds the tools and benchmarks report.
#include <chrono>

namespace osm_graph_slam {

inline double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace osm_graph_slam
