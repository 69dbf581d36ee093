// backend_benchmark: the cost of a back-end update as the graph grows, windowed
// (optimization_window) against a full batch of the same graph in the same run.
//
//   (the options: backend_benchmark --help)
//
// A vehicle drives laps of a circuit of L keyframes (2 m apart) with drifting, noisy odometry;
// from the second lap on, every keyframe closes a loop to the one a lap before (as in the soak,
// scripts/soak.sh). update() runs every K keyframes. At C checkpoints the tool prints the last
// windowed update's ms and a forced full batch's ms on the same graph, and their ratio; the last
// line compares the trajectory's error after the final full batch with a back-end that never
// windowed (full batches at the checkpoints only).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "osm_graph_slam/slam/graph_backend.h"
#include "support/command_line.h"

namespace {

using namespace osm_graph_slam;
using Clock = std::chrono::steady_clock;

struct Args {
  int keyframes = 4000;
  int window = 300;
  int every = 10;
  int lap = 120;
  int checkpoints = 4;
};

/// The command line into a; an exit status when the tool should stop (--help, a usage error).
std::optional<int> parse(int argc, char** argv, Args& a) {
  tools::CommandLine cli("backend_benchmark",
                         "The cost of a back-end update as the graph grows, windowed "
                         "(optimization_window) against a full batch of the same graph in the "
                         "same run.");
  cli.option("--keyframes", "N", "keyframes driven", &a.keyframes)
      .option("--window", "W", "the optimisation window in keyframes", &a.window)
      .option("--every", "K", "update() every K keyframes", &a.every)
      .option("--lap", "L", "keyframes per lap of the circuit (2 m apart; > 2)", &a.lap)
      .option("--checkpoints", "C", "checkpoints with a forced full batch", &a.checkpoints);
  if (const auto exit_code = cli.parse(argc, argv)) return exit_code;
  if (!(a.keyframes > 0 && a.window > 0 && a.every > 0 && a.lap > 2 && a.checkpoints > 0))
    return cli.fail("every value must be > 0 and --lap > 2");
  return std::nullopt;
}

/// The true pose of keyframe i: a circle of `lap` keyframes 2 m apart, heading along it.
Eigen::Isometry3d truePose(int i, int lap) {
  const double radius = 2.0 / (2.0 * std::sin(M_PI / lap));
  const double a = 2.0 * M_PI * i / lap;
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = Eigen::Vector3d(radius * std::sin(a), radius * (1.0 - std::cos(a)), 0.0);
  p.linear() = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

/// Scan-matching-like odometry: each step's truth with 1 cm and 1 mrad noise, 0.5 mrad yaw bias.
class Odometry {
 public:
  explicit Odometry(int lap) : lap_(lap) {}
  Eigen::Isometry3d next(int i) {
    if (i > 0) {
      Eigen::Isometry3d step = truePose(i - 1, lap_).inverse() * truePose(i, lap_);
      step.translation() += Eigen::Vector3d(noise_(rng_), noise_(rng_), 0.0);
      step.linear() =
          step.linear() *
          Eigen::AngleAxisd(5e-4 + 0.1 * noise_(rng_), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      pose_ = pose_ * step;
    }
    return pose_;
  }

 private:
  int lap_;
  std::mt19937 rng_{7};
  std::normal_distribution<double> noise_{0.0, 0.01};
  Eigen::Isometry3d pose_ = Eigen::Isometry3d::Identity();
};

void feed(GraphBackend& backend, Odometry& odom, int i, int lap) {
  KeyframeInput kf;
  kf.id = static_cast<uint64_t>(i);
  kf.stamp = 1.0 + i;
  kf.odom_pose = odom.next(i);
  kf.accum_distance = 2.0 * i;
  kf.odom_fitness = 0.05;
  backend.addKeyframe(kf);
  if (i < lap) return;
  LoopClosureInput loop;  // to the same place a lap before, measured with 5 cm / 5 mrad
  loop.from_id = kf.id;
  loop.to_id = kf.id - lap;
  loop.relative_pose = truePose(i - lap, lap).inverse() * truePose(i, lap);
  loop.information.diagonal() << 400, 400, 400, 4e4, 4e4, 4e4;
  backend.addLoopClosure(loop);
}

double ms(const Clock::time_point& t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double meanError(const GraphBackend& backend, int lap) {
  double sum = 0.0;
  const std::vector<KeyframeState> kfs = backend.keyframes();
  for (const KeyframeState& k : kfs)
    sum += (k.map_pose.translation() - truePose(static_cast<int>(k.id), lap).translation()).norm();
  return kfs.empty() ? 0.0 : sum / kfs.size();
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  if (const auto exit_code = parse(argc, argv, a)) return *exit_code;
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = true;
  params.schedule.optimization_window = a.window;
  GraphBackend windowed(params);
  params.schedule.optimization_window = 0;
  GraphBackend reference(params);  // full batches only, at the checkpoints: the result to match
  Odometry odom_w(a.lap), odom_r(a.lap);

  std::printf("%10s %14s %14s %8s %10s\n", "keyframes", "windowed [ms]", "full [ms]", "ratio",
              "full batches for a loop");
  const int step = std::max(a.every, a.keyframes / a.checkpoints);
  size_t loop_batches = 0;
  double windowed_ms = 0.0;
  for (int i = 0; i < a.keyframes; ++i) {
    feed(windowed, odom_w, i, a.lap);
    feed(reference, odom_r, i, a.lap);
    if ((i + 1) % a.every != 0) continue;
    auto t0 = Clock::now();
    const BackendUpdateReport r = windowed.update();
    windowed_ms = ms(t0);
    loop_batches += r.full_batch_for_loop;
    if ((i + 1) % step != 0) continue;
    reference.update();
    t0 = Clock::now();
    windowed.update(true);  // the same graph as a full batch: the reference cost
    const double full_ms = ms(t0);
    std::printf("%10d %14.1f %14.1f %8.3f %10zu\n", i + 1, windowed_ms, full_ms,
                windowed_ms / std::max(1e-3, full_ms), loop_batches);
  }
  windowed.update(true);
  reference.update(true);
  std::printf(
      "mean position error after the final full batch: windowed %.3f m, never windowed "
      "%.3f m\n",
      meanError(windowed, a.lap), meanError(reference, a.lap));
  return 0;
}
