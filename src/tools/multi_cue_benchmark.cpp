// multi_cue_benchmark: multi-cue photometric registration (multi_cue/, issue 55) against the GICP
// registration of the keyframe tracker on the same consecutive pairs of real scans, in the same
// run: scan k+1 registered to scan k by both, each from its own constant-velocity guess.
// Prints milliseconds per scan per stage (multi-cue: projection, normals, gradients,
// Gauss-Newton; GICP: prefilter, registration), their ratio, and how far the two relative
// motions are apart (translation cm, rotation deg: median, 90th percentile, worst).
// --simulated N: consecutive pairs of a simulated drive against the true motion instead (the
// real drive has no ground truth; the defaults were chosen on both, doc/multi_cue.md).
// --trackers: the whole KeyframeTracker instead, with tracker gicp and with tracker multi_cue
// (config/scan_matching.yaml otherwise), on the same scans in the same run: scans tracked, ms
// per scan, and how far the two odometry trajectories end apart.
//
//   (the options: multi_cue_benchmark --help)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/multi_cue/multi_cue_registration.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/odometry/params_io.h"
#include "osm_graph_slam/registration/registration.h"
#include "osm_graph_slam/sim/simulator.h"
#include "support/command_line.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// CPU time of the process [ms]: on a machine shared with other jobs the wall clock also counts
/// the time this process waited for a core; the CPU time does not.
double cpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * t.tv_sec + 1e-6 * t.tv_nsec;
}

/// Per-scan milliseconds of each stage, summed over the scans.
struct MultiCueTimes {
  double projection = 0.0, normals = 0.0, gradients = 0.0, gauss_newton = 0.0;
  double total() const { return projection + normals + gradients + gauss_newton; }
};

struct GicpTimes {
  double prefilter = 0.0, registration = 0.0;
  double total() const { return prefilter + registration; }
};

struct PairResult {
  Eigen::Isometry3d multi_cue = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d gicp = Eigen::Isometry3d::Identity();
  bool multi_cue_converged = false, gicp_converged = false;
  int iterations = 0, inliers = 0;
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * (v.size() - 1) + 0.5))];
}

/// Registers every scan to the one before with the multi-cue registration; each scan's pyramid
/// is built once and serves as the next pair's model.
void runMultiCue(const std::vector<PointCloud>& scans, const SphericalProjectionParams& projection,
                 const MultiCueParams& params, const SurfaceContinuityParams& continuity,
                 MultiCueTimes& times, std::vector<PairResult>& pairs) {
  const MultiCueRegistration registration(params, continuity);
  MultiCueBuildTimes build;
  MultiCuePyramid model = buildPyramid(scans.front(), projection, params.pyramid_levels, continuity,
                                       &build, params.num_threads);
  times.projection += build.projection_ms;
  times.normals += build.normals_ms;
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  for (size_t k = 1; k < scans.size(); ++k) {
    MultiCuePyramid current = buildPyramid(scans[k], projection, params.pyramid_levels, continuity,
                                           &build, params.num_threads);
    times.projection += build.projection_ms;
    times.normals += build.normals_ms;
    const MultiCueResult r = registration.align(model, current, guess);
    times.gradients += r.gradients_ms;
    times.gauss_newton += r.time_ms - r.gradients_ms;
    PairResult& pair = pairs[k - 1];
    pair.multi_cue = r.transform;
    pair.multi_cue_converged = r.converged;
    pair.iterations = r.iterations;
    pair.inliers = r.inliers;
    guess = r.transform;  // constant velocity
    model = std::move(current);
  }
}

/// The same pairs with the keyframe tracker's GICP on prefiltered scans (the tracker's input).
void runGicp(const std::vector<PointCloud>& scans, const RegistrationParams& params,
             GicpTimes& times, std::vector<PairResult>& pairs) {
  const CloudPrefilter prefilter;
  auto registration = createRegistration(params);
  auto start = Clock::now();
  PointCloudConstPtr target = prefilter.filter(scans.front()).cloud;
  times.prefilter += msSince(start);
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  for (size_t k = 1; k < scans.size(); ++k) {
    start = Clock::now();
    PointCloudConstPtr source = prefilter.filter(scans[k]).cloud;
    times.prefilter += msSince(start);
    start = Clock::now();
    registration->setTarget(target);
    const RegistrationResult r = registration->align(source, guess);
    times.registration += msSince(start);
    pairs[k - 1].gicp = r.transform;
    pairs[k - 1].gicp_converged = r.converged;
    guess = r.transform;
    target = source;
  }
}

/// Consecutive scans of a simulated drive (a small procedural city, HDL-64E, no motion
/// distortion) registered from identity, against the true motion: what the cue weights and
/// thresholds were chosen on, since the real drive has no ground truth.
int runSimulated(size_t pair_count, const SphericalProjectionParams& projection,
                 const MultiCueParams& params, const SurfaceContinuityParams& continuity) {
  sim::SimulationParams sim_params;
  sim_params.seed = 5;
  sim_params.city.blocks_x = 4;
  sim_params.city.blocks_y = 3;
  sim_params.route.length = 600.0;
  sim::UrbanSimulator sim;
  std::string error;
  if (!sim.build(sim_params, &error)) {
    std::cerr << "multi_cue_benchmark: simulation: " << error << "\n";
    return 1;
  }
  const MultiCueRegistration registration(params, continuity);
  const size_t step = std::max<size_t>(1, (sim.numScans() - 12) / std::max<size_t>(1, pair_count));
  std::vector<double> t_cm, r_deg;
  double motion_m = 0.0;
  int converged = 0;
  double ms = 0.0;
  for (size_t k = 10; k + 1 < sim.numScans() && t_cm.size() < pair_count; k += step) {
    const Eigen::Isometry3d truth =
        sim.sensorPose(sim.scanTime(k)).inverse() * sim.sensorPose(sim.scanTime(k + 1));
    const MultiCuePyramid model =
        buildPyramid(sim.simulate(k).cloud, projection, params.pyramid_levels, continuity, nullptr,
                     params.num_threads);
    const MultiCuePyramid current =
        buildPyramid(sim.simulate(k + 1).cloud, projection, params.pyramid_levels, continuity,
                     nullptr, params.num_threads);
    const auto align_start = Clock::now();
    const MultiCueResult r = registration.align(model, current, Eigen::Isometry3d::Identity());
    ms += msSince(align_start);
    motion_m += truth.translation().norm();
    const Eigen::Isometry3d e = truth.inverse() * r.transform;
    t_cm.push_back(100.0 * e.translation().norm());
    r_deg.push_back(Eigen::AngleAxisd(e.linear()).angle() * 180.0 / M_PI);
    converged += r.converged;
  }
  const double n = std::max<size_t>(1, t_cm.size());
  double mean_t = 0.0, mean_r = 0.0;
  for (size_t i = 0; i < t_cm.size(); ++i) mean_t += t_cm[i] / n, mean_r += r_deg[i] / n;
  std::printf(
      "%zu simulated pairs (from identity, %.2f m apart on average): error to the truth: "
      "translation "
      "mean %.2f cm, median %.2f, worst %.2f; rotation mean %.4f deg, worst %.4f; "
      "converged %d/%zu; Gauss-Newton %.2f ms per pair\n",
      t_cm.size(), motion_m / n, mean_t, quantile(t_cm, 0.5), quantile(t_cm, 1.0), mean_r,
      quantile(r_deg, 1.0), converged, t_cm.size(), ms / n);
  return 0;
}

/// One tracker's odometry over the scans: its poses, what it did with each scan, and its time.
struct TrackerRun {
  std::vector<Eigen::Isometry3d> poses;
  int matched = 0, failed = 0, reanchored = 0;
  uint64_t keyframes = 0, tracker_keyframes = 0;
  double ms = 0.0;  ///< track() wall clock over all scans (the prefilter is not in it)
  std::vector<double> fitness;
};

TrackerRun runTracker(const KeyframeTrackerParams& params, const std::vector<PointCloud>& scans,
                      const std::vector<PointCloudConstPtr>& filtered, double rate) {
  KeyframeTracker tracker(params);
  TrackerRun run;
  for (size_t k = 0; k < scans.size(); ++k) {
    // The raw scan is shared without a copy: only the multi-cue tracker reads it.
    const PointCloudConstPtr raw(&scans[k], [](const PointCloud*) {});
    const auto start = Clock::now();
    const TrackResult r = tracker.track(k / rate, filtered[k], std::nullopt, raw);
    run.ms += msSince(start);
    if (!r.notice.empty()) std::printf("  (%s)\n", r.notice.c_str());
    run.matched += r.status == TrackStatus::kMatched;
    run.failed += r.status == TrackStatus::kMatchFailed;
    run.reanchored += r.status == TrackStatus::kReanchored;
    if (r.status == TrackStatus::kMatched) run.fitness.push_back(r.registration.fitness);
    if (r.failed())
      std::printf("  %s: scan %zu %s: %s\n", params.tracker.c_str(), k, toString(r.status),
                  r.message.c_str());
    run.poses.push_back(r.pose);
  }
  run.keyframes = tracker.keyframeCount();
  run.tracker_keyframes = tracker.trackerKeyframeCount();
  return run;
}

/// Both trackers (config/scan_matching.yaml, tracker gicp and multi_cue) on the same scans.
int runTrackers(const std::vector<PointCloud>& scans, double rate, int threads,
                const std::string& overrides) {
  KeyframeTrackerParams params;
  for (const std::string& file :
       {std::string(OGS_SOURCE_DIR) + "/config/scan_matching.yaml", overrides}) {
    if (file.empty()) continue;
    const YamlParamReader yaml = YamlParamReader::fromFile(file);
    if (!yaml.ok()) {
      std::cerr << "multi_cue_benchmark: " << yaml.error() << "\n";
      return 1;
    }
    readParams(yaml, params);
  }
  params.registration.num_threads = params.multi_cue.registration.num_threads = threads;
  const CloudPrefilter prefilter;
  std::vector<PointCloudConstPtr> filtered;
  for (const PointCloud& scan : scans) filtered.push_back(prefilter.filter(scan).cloud);
  params.tracker = "gicp";
  const TrackerRun gicp = runTracker(params, scans, filtered, rate);
  params.tracker = "multi_cue";
  const TrackerRun mc = runTracker(params, scans, filtered, rate);
  const size_t n = scans.size();
  for (const auto* run : {&gicp, &mc}) {
    std::printf(
        "%-9s: %zu scans, matched %d, failed %d, re-anchored %d, %lu keyframes (%lu tracker "
        "keyframes), %.2f ms/scan, fitness median %.4g worst %.4g\n",
        run == &gicp ? "gicp" : "multi_cue", n, run->matched, run->failed, run->reanchored,
        static_cast<unsigned long>(run->keyframes),
        static_cast<unsigned long>(run->tracker_keyframes), run->ms / n,
        quantile(run->fitness, 0.5), quantile(run->fitness, 1.0));
  }
  double worst_m = 0.0, worst_deg = 0.0, length = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Isometry3d d = gicp.poses[k].inverse() * mc.poses[k];
    worst_m = std::max(worst_m, d.translation().norm());
    worst_deg = std::max(worst_deg, Eigen::AngleAxisd(d.linear()).angle() * 180.0 / M_PI);
    if (k > 0) length += (gicp.poses[k - 1].inverse() * gicp.poses[k]).translation().norm();
  }
  const Eigen::Isometry3d end = gicp.poses.back().inverse() * mc.poses.back();
  std::printf(
      "multi_cue vs gicp odometry over %.1f m: end %.3f m, %.3f deg; worst over the drive %.3f m, "
      "%.3f deg; ms/scan ratio %.2f\n",
      length, end.translation().norm(), Eigen::AngleAxisd(end.linear()).angle() * 180.0 / M_PI,
      worst_m, worst_deg, mc.ms / gicp.ms);
  return 0;
}

void printStage(const char* name, double total_ms, size_t scans) {
  std::printf("  %-28s %7.2f ms/scan\n", name, total_ms / scans);
}

}  // namespace

int main(int argc, char** argv) {
  reuseFreedMemory();  // scan-sized buffers stay in the heap (common/memory_tuning.h)
  std::string dir, sensor = "hdl64e", tracker_config;
  size_t max_scans = 0, simulated_pairs = 0;
  int threads = 1, cols = 0;
  bool skip_gicp = false, trackers = false;
  double rate = 10.0;
  MultiCueParams params;
  SurfaceContinuityParams continuity;
  CommandLine cli("multi_cue_benchmark",
                  "Multi-cue photometric registration against the tracker's GICP on the same "
                  "consecutive pairs of real scans, in the same run: ms per scan per stage, the "
                  "ratio, and the relative motions' agreement.");
  cli.option("--scans", "DIR", "a folder of KITTI .bin scans (required unless --simulated)", &dir)
      .option("--simulated", "N",
              "instead: N consecutive pairs of a simulated drive, errors to the true motion",
              &simulated_pairs)
      .option("--max-scans", "N", "use at most N scans (0: all)", &max_scans)
      .option("--sensor", "NAME", "projection preset: hdl64e | os1_64", &sensor)
      .option("--cols", "N", "image columns (0: the preset's)", &cols)
      .option("--levels", "L", "pyramid levels", &params.pyramid_levels)
      .option("--model-stride", "S", "render every model pixel (1) or a checkerboard half (2)",
              &params.model_stride)
      .option("--iterations", "N", "Gauss-Newton iterations per level",
              &params.max_iterations_per_level)
      .option("--range-weight", "W", "range cue weight [1/m^2]", &params.range_weight)
      .option("--intensity-weight", "W", "intensity cue weight", &params.intensity_weight)
      .option("--normal-weight", "W", "normal cue weight", &params.normal_weight)
      .option("--kernel", "NAME", "huber | cauchy", &params.kernel)
      .option("--kernel-width", "W", "robust kernel width", &params.kernel_width)
      .option("--max-range-jump", "RATIO", "neighbours on one surface differ by less than this",
              &continuity.max_range_jump_ratio)
      .option("--range-gate", "M", "outlier gate on the range difference [m]", &params.range_gate)
      .option("--translation-epsilon", "M", "convergence on the step [m]",
              &params.translation_epsilon)
      .option("--rotation-epsilon", "RAD", "convergence on the step [rad]",
              &params.rotation_epsilon)
      .option("--threads", "N", "threads of both registrations (0: all hardware threads)", &threads)
      .flag("--no-gicp", "multi-cue only (tuning; no ratio, no agreement)", &skip_gicp)
      .flag("--trackers",
            "instead: the keyframe tracker with tracker gicp and multi_cue on the same scans "
            "(config/scan_matching.yaml; --threads): scans tracked, ms per scan, end difference",
            &trackers)
      .option("--rate", "HZ", "--trackers: the scan rate (stamps)", &rate)
      .option("--tracker-config", "YAML",
              "--trackers: scan_matching keys over config/scan_matching.yaml", &tracker_config);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  SphericalProjectionParams projection = sensor == "os1_64" ? SphericalProjectionParams::os1_64()
                                                            : SphericalProjectionParams::hdl64e();
  if (cols > 0) projection.cols = cols;
  if (const std::string why = projection.validate(); !why.empty()) return cli.fail(why);
  if (const std::string why = params.validate(); !why.empty()) return cli.fail(why);
  params.num_threads = threads;
  if (simulated_pairs > 0) return runSimulated(simulated_pairs, projection, params, continuity);
  if (dir.empty()) return cli.fail("--scans DIR is required (or --simulated N)");

  const std::vector<std::string> files = listFiles(dir, ".bin");
  std::vector<PointCloud> scans;
  for (const auto& file : files) {
    if (max_scans > 0 && scans.size() >= max_scans) break;
    PointCloud cloud;
    std::string error;
    if (!readKittiBin(file, cloud, &error)) return cli.fail(error);
    scans.push_back(std::move(cloud));
  }
  if (scans.size() < 2) return cli.fail("fewer than 2 .bin scans in '" + dir + "'");
  if (trackers) return runTrackers(scans, rate, threads, tracker_config);

  std::vector<PairResult> pairs(scans.size() - 1);
  MultiCueTimes mc;
  GicpTimes gicp;
  const double mc_cpu_start = cpuMs();
  runMultiCue(scans, projection, params, continuity, mc, pairs);
  const double mc_cpu = cpuMs() - mc_cpu_start;
  RegistrationParams gicp_params = KeyframeTrackerParams().registration;
  gicp_params.num_threads = threads;
  const double gicp_cpu_start = cpuMs();
  if (!skip_gicp) runGicp(scans, gicp_params, gicp, pairs);
  const double gicp_cpu = cpuMs() - gicp_cpu_start;

  std::vector<double> dt_cm, dr_deg, iterations, inliers;
  int mc_converged = 0, gicp_converged = 0;
  for (const PairResult& p : pairs) {
    const Eigen::Isometry3d d = p.gicp.inverse() * p.multi_cue;
    dt_cm.push_back(100.0 * d.translation().norm());
    dr_deg.push_back(Eigen::AngleAxisd(d.linear()).angle() * 180.0 / M_PI);
    iterations.push_back(p.iterations);
    inliers.push_back(p.inliers);
    mc_converged += p.multi_cue_converged;
    gicp_converged += p.gicp_converged;
  }
  const size_t n = scans.size() - 1;  // registered scans
  std::printf("%zu scans, %zu pairs; projection %dx%d, %d levels\n", scans.size(), n,
              projection.rows, projection.cols, params.pyramid_levels);
  std::printf("multi-cue (%d thread(s)):\n", threads);
  printStage("projection", mc.projection, n);
  printStage("normals", mc.normals, n);
  printStage("gradients", mc.gradients, n);
  printStage("Gauss-Newton", mc.gauss_newton, n);
  printStage("total", mc.total(), n);
  std::printf("  CPU time                     %7.2f ms/scan (all threads)\n", mc_cpu / n);
  std::printf("  converged %d/%zu, iterations median %.0f, inliers median %.0f\n", mc_converged, n,
              quantile(iterations, 0.5), quantile(inliers, 0.5));
  std::printf("GICP (fast_gicp, the tracker's parameters, %d thread(s)):\n", threads);
  printStage("prefilter", gicp.prefilter, n);
  printStage("registration", gicp.registration, n);
  printStage("total", gicp.total(), n);
  std::printf("  CPU time                     %7.2f ms/scan (all threads)\n", gicp_cpu / n);
  std::printf("  converged %d/%zu\n", gicp_converged, n);
  std::printf("ratio multi-cue / GICP: %.2f (registration alone: %.2f; CPU time: %.2f)\n",
              mc.total() / gicp.total(), mc.total() / gicp.registration, mc_cpu / gicp_cpu);
  std::printf(
      "motion agreement with GICP: translation median %.2f cm, p90 %.2f, worst %.2f; "
      "rotation median %.3f deg, p90 %.3f, worst %.3f\n",
      quantile(dt_cm, 0.5), quantile(dt_cm, 0.9), quantile(dt_cm, 1.0), quantile(dr_deg, 0.5),
      quantile(dr_deg, 0.9), quantile(dr_deg, 1.0));
  return 0;
}
