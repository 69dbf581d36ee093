// sim_benchmark: speed of the urban simulator's stages, and the grid ray caster against testing
// every wall and primitive (the reference, measured in the same run).
//   (the options: sim_benchmark --help)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "osm_graph_slam/sim/simulator.h"
#include "support/command_line.h"

using namespace osm_graph_slam::sim;

namespace {
double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

int main(int argc, char** argv) {
  int scans = 20;
  bool json = false;
  osm_graph_slam::tools::CommandLine cli(
      "sim_benchmark",
      "Speed of the urban simulator's stages, and the grid ray caster against testing every wall "
      "and primitive (the reference, measured in the same run).");
  cli.option("--scans", "N", "scans to simulate", &scans).flag("--json", "print JSON", &json);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  auto t0 = std::chrono::steady_clock::now();
  UrbanSimulator sim;
  std::string error;
  if (!sim.build(SimulationParams(), &error)) {
    std::fprintf(stderr, "sim_benchmark: %s\n", error.c_str());
    return 1;
  }
  const double build_ms = msSince(t0);
  size_t points = 0;
  t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < scans; ++k) points += sim.simulate(size_t(k) * 10).cloud.size();
  const double scan_ms = msSince(t0) / scans;
  // Reference: one scan without the grid.
  UrbanSimulator brute;
  brute.build(SimulationParams(), &error);
  const_cast<World&>(brute.scene().world).use_grid = false;
  t0 = std::chrono::steady_clock::now();
  const size_t ref_points = brute.simulate(0).cloud.size();
  const double ref_ms = msSince(t0);
  const double first_ms = [&] {
    auto t = std::chrono::steady_clock::now();
    sim.simulate(0);
    return msSince(t);
  }();
  if (json) {
    std::printf(
        "{\"build_ms\": %.1f, \"scan_ms\": %.2f, \"scans_per_s\": %.2f, "
        "\"points_per_scan\": %.0f, \"reference_bruteforce_scan_ms\": %.1f, "
        "\"grid_scan0_ms\": %.2f, \"speedup_vs_bruteforce\": %.1f, \"ref_points\": %zu}\n",
        build_ms, scan_ms, 1000.0 / scan_ms, double(points) / scans, ref_ms, first_ms,
        ref_ms / first_ms, ref_points);
  } else {
    std::printf(
        "world+route build: %.1f ms\nscan (grid, TBB): %.2f ms  -> %.1f scans/s, %.0f "
        "points/scan\nreference scan 0 without grid: %.1f ms, with grid: %.2f ms, "
        "ratio %.1fx\n",
        build_ms, scan_ms, 1000.0 / scan_ms, double(points) / scans, ref_ms, first_ms,
        ref_ms / first_ms);
  }
  return 0;
}
