// offline_radar_slam: radar odometry (RadART-SLAM front-end) over a MulRan-layout drive, written
// as offline_slam writes its runs: odometry_tum.txt, trajectory_tum.txt, ground_truth_tum.txt
// and timing.json in --output, a timing report (ms per stage, ratio to real time at the radar's
// 4 Hz) and, when global_pose.csv exists, the accuracy (KITTI drift, ATE) — see doc/radar.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/radar/radar_drive.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

namespace {

/// KITTI drift, ATE (first pose aligned, and best-fit aligned) and RPE of a planar trajectory.
nlohmann::json accuracyOf(const Trajectory& estimate, const Trajectory& truth) {
  TrajectoryEvalOptions eo;
  eo.planar = true;
  eo.alignment = TrajectoryAlignment::kFirstPose;
  eo.max_time_difference = 0.01;
  const TrajectoryErrors e = evaluateTrajectory(estimate, truth, eo);
  // With GNSS the map frame is still the first keyframe's, whose heading error the fixes cannot
  // undo: the best rigid fit shows what the fixes hold.
  eo.alignment = TrajectoryAlignment::kUmeyamaSE3;
  const TrajectoryErrors aligned = evaluateTrajectory(estimate, truth, eo);
  double length = 0;
  for (size_t k = 1; k < truth.size(); ++k)
    length += (truth[k].pose.translation() - truth[k - 1].pose.translation()).norm();
  return {{"length_m", length},
          {"kitti_segments", e.kitti_segments},
          {"kitti_trans_percent", e.kitti_trans_percent},
          {"kitti_rot_deg_per_100m", e.kitti_rot_deg_per_100m},
          {"ate_rmse_m", e.ate.rmse},
          {"ate_max_m", e.ate.max},
          {"ate_aligned_rmse_m", aligned.ate.rmse},
          {"ate_aligned_max_m", aligned.ate.max},
          {"rpe_trans_mean_m", e.rpe_trans.mean},
          {"rpe_rot_mean_deg", e.rpe_rot.mean * 180 / M_PI},
          {"end_drift_percent", length > 0 ? 100.0 * e.ate_per_pose.back() / length : 0.0}};
}

/// Each accepted loop's measurement against the ground truth of its two keyframes: the largest
/// errors and how many exceed max_m or max_deg (false loops).
nlohmann::json loopErrors(const radar::RadarDriveResult& r, double max_m, double max_deg,
                          std::vector<std::pair<double, double>>* errors) {
  const double origin = r.odometry.empty() ? 0.0 : r.odometry.front().stamp - r.steps.front().time;
  auto truthAt = [&](double t, Eigen::Isometry2d& T) {
    for (const StampedPose& p : r.ground_truth)
      if (std::abs(p.stamp - (origin + t)) < 1e-4) {
        T.setIdentity();
        T.linear() = p.pose.linear().topLeftCorner<2, 2>();
        T.translation() = p.pose.translation().head<2>();
        return true;
      }
    return false;
  };
  int checked = 0, wrong = 0;
  double worst_m = 0, worst_deg = 0;
  for (const radar::RadarLoop& l : r.loops) {
    Eigen::Isometry2d a, b;
    if (!truthAt(l.from_time, a) || !truthAt(l.to_time, b)) {
      if (errors) errors->push_back({NAN, NAN});  // rows stay aligned with the loops
      continue;
    }
    const Eigen::Isometry2d e = (a.inverse() * b).inverse() * l.measurement;
    const double m = e.translation().norm();
    const double deg = std::abs(yawOf(e)) * 180 / M_PI;
    if (errors) errors->push_back({m, deg});
    ++checked;
    if (m > max_m || deg > max_deg) ++wrong;
    worst_m = std::max(worst_m, m);
    worst_deg = std::max(worst_deg, deg);
  }
  return {{"checked", checked},        {"false", wrong},
          {"false_if_above_m", max_m}, {"false_if_above_deg", max_deg},
          {"worst_m", worst_m},        {"worst_deg", worst_deg}};
}

/// One row per accepted loop: keyframes, times, measurement, fit, and (with ground truth) error.
std::string loopsCsv(const std::vector<radar::RadarLoop>& loops,
                     const std::vector<std::pair<double, double>>& errors) {
  std::string csv =
      "from,to,from_time,to_time,x,y,yaw_deg,rms,overlap,by_scan_context,error_m,error_deg\n";
  char line[256];
  for (size_t i = 0; i < loops.size(); ++i) {
    const radar::RadarLoop& l = loops[i];
    const Eigen::Isometry2d& T = l.measurement;
    const bool e = i < errors.size();
    std::snprintf(line, sizeof(line), "%d,%d,%.6f,%.6f,%.3f,%.3f,%.3f,%.4f,%.3f,%d,%s,%s\n", l.from,
                  l.to, l.from_time, l.to_time, T.translation().x(), T.translation().y(),
                  yawOf(T) * 180 / M_PI, l.rms, l.overlap, l.by_scan_context ? 1 : 0,
                  e ? std::to_string(errors[i].first).c_str() : "",
                  e ? std::to_string(errors[i].second).c_str() : "");
    csv += line;
  }
  return csv;
}

/// The run's report (timing.json): timing per stage, loops, navigation and, with ground truth,
/// the accuracy; loop_errors gets each loop's error against the truth.
nlohmann::json radarReport(const radar::RadarDriveResult& r,
                           const radar::RadarSlamParams& slam_params, const std::string& mulran,
                           double wall_s, std::vector<std::pair<double, double>>* loop_errors_out) {
  const radar::RadarOdometryParams& params = slam_params.odometry;
  const double ms_scan =
      r.ms_read + r.ms_features + r.ms_matching + r.ms_motion + r.ms_registration;
  nlohmann::json j;
  j["drive"] = mulran;
  j["scans"] = r.scans;
  j["skipped"] = r.skipped.size();
  j["ransac_failures"] = r.failed;
  j["detector"] = params.features.detector;
  j["motion_compensation"] = params.motion.motion_compensation;
  j["doppler_beta"] = params.motion.doppler_correction ? params.motion.doppler_beta : 0.0;
  j["registration"] = params.registration.enabled;
  j["registered_sweeps"] = r.registered;
  j["timing_ms_per_scan"] = {
      {"read", r.ms_read},     {"features", r.ms_features},         {"matching", r.ms_matching},
      {"motion", r.ms_motion}, {"registration", r.ms_registration}, {"total", ms_scan}};
  j["wall_s"] = wall_s;
  j["drive_span_s"] = r.span_s;
  j["real_time_ratio_4hz"] = ms_scan > 0 ? 250.0 / ms_scan : 0.0;
  const radar::RadarLoopStats& ls = r.loop_stats;
  j["keyframes"] = r.keyframes;
  j["loops"] = {{"enabled", slam_params.loop.enabled},
                {"accepted", ls.accepted},
                {"by_scan_context",
                 std::count_if(r.loops.begin(), r.loops.end(),
                               [](const radar::RadarLoop& l) { return l.by_scan_context; })},
                {"candidates", ls.candidates},
                {"rejected_registration", ls.rejected_registration},
                {"rejected_gate", ls.rejected_gate},
                {"ms_per_keyframe",
                 r.keyframes ? (ls.ms_descriptor + ls.ms_search + ls.ms_verify + ls.ms_optimise) /
                                   double(r.keyframes)
                             : 0.0}};
  const radar::RadarNavStats& ns = r.nav_stats;
  j["navigation"] = {{"gnss_enabled", slam_params.nav.gnss_enabled},
                     {"gnss_fixes", ns.gnss_fixes},
                     {"gnss_rejected_sigma", ns.gnss_rejected_sigma},
                     {"gnss_out_of_order", ns.gnss_out_of_order},
                     {"gnss_edges", ns.gnss_edges},
                     {"anchored", ns.anchored},
                     {"imu_enabled", slam_params.nav.imu_enabled},
                     {"imu_samples", ns.imu_samples},
                     {"imu_out_of_order", ns.imu_out_of_order},
                     {"imu_edges", ns.imu_edges},
                     {"imu_missing", ns.imu_missing}};
  if (!r.ground_truth.empty()) {
    j["loops"]["against_ground_truth"] = loopErrors(r, 1.0, 2.0, loop_errors_out);
    j["accuracy"] = accuracyOf(r.odometry, r.ground_truth);
    j["accuracy_slam"] = accuracyOf(r.trajectory, r.ground_truth);
  }
  return j;
}

/// The report as text.
void printReport(const radar::RadarDriveResult& r, const nlohmann::json& j) {
  const double ms_scan = j["timing_ms_per_scan"]["total"].get<double>();
  std::printf("offline_radar_slam: %d sweeps (%zu skipped, %d RANSAC failures) over %.1f s\n",
              r.scans, r.skipped.size(), r.failed, r.span_s);
  std::printf(
      "time per sweep: read %.1f ms, features %.1f ms, matching %.1f ms, motion %.1f ms,"
      " registration %.1f ms, total %.1f ms = %.2fx real time at 4 Hz\n",
      r.ms_read, r.ms_features, r.ms_matching, r.ms_motion, r.ms_registration, ms_scan,
      ms_scan > 0 ? 250.0 / ms_scan : 0.0);
  std::printf("loops: %s\n", j["loops"].dump().c_str());
  std::printf("navigation: %s\n", j["navigation"].dump().c_str());
  if (j.contains("accuracy")) {
    std::printf("odometry: %s\n", j["accuracy"].dump().c_str());
    std::printf("with loops: %s\n", j["accuracy_slam"].dump().c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string mulran, output, config;
  bool json = false;
  radar::RadarSlamParams slam_params;
  radar::RadarOdometryParams& params = slam_params.odometry;
  radar::RadarDriveOptions options;
  std::string detector, beta;
  bool no_mc = false, no_doppler = false, no_registration = false, no_loops = false;
  bool no_gnss = false, no_imu = false;
  tools::CommandLine cli(
      "offline_radar_slam",
      "Radar odometry (RadART-SLAM front-end), loops and GNSS/IMU over a MulRan-layout drive, "
      "written as offline_slam writes its runs (see doc/radar.md).");
  cli.option("--mulran", "DIR", "the MulRan sequence folder", &mulran)
      .required()
      .option("--output", "DIR",
              "where odometry_tum.txt, trajectory_tum.txt, ground_truth_tum.txt, loops.csv and "
              "timing.json go",
              &output)
      .required()
      .option("--config", "radar.yaml", "radar parameters", &config)
      .flag("--json", "print the report as JSON", &json)
      .option("--max-scans", "N", "read at most N sweeps (0: all)", &options.max_scans)
      .option("--detector", "kstrongest|cfar", "the feature detector", &detector)
      .option("--beta", "S", "the Doppler beta", &beta)
      .flag("--no-motion-compensation", "no motion compensation", &no_mc)
      .flag("--no-doppler", "no Doppler correction", &no_doppler)
      .flag("--no-registration", "no sweep registration", &no_registration)
      .flag("--no-loops", "no loop closures", &no_loops)
      .flag("--no-gnss", "no GNSS", &no_gnss)
      .flag("--no-imu", "no IMU", &no_imu);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (!config.empty()) {
    const YamlParamReader yaml = YamlParamReader::fromFile(config);
    std::string error;
    if (!yaml.ok() || !radar::readSlamParams(yaml, slam_params, &error)) {
      std::fprintf(stderr, "offline_radar_slam: %s\n",
                   yaml.ok() ? error.c_str() : yaml.error().c_str());
      return 2;
    }
  }
  if (!detector.empty()) params.features.detector = detector;
  if (!beta.empty()) params.motion.doppler_beta = std::atof(beta.c_str());
  if (no_mc) params.motion.motion_compensation = false;
  if (no_doppler) params.motion.doppler_correction = false;
  if (no_registration) params.registration.enabled = false;
  if (no_loops) slam_params.loop.enabled = false;
  if (no_gnss) slam_params.nav.gnss_enabled = false;
  if (no_imu) slam_params.nav.imu_enabled = false;

  const auto t0 = std::chrono::steady_clock::now();
  const radar::RadarDriveResult r = radar::runMulranRadarSlam(mulran, slam_params, options);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const std::string& s : r.skipped)
    std::fprintf(stderr, "offline_radar_slam: skipped: %s\n", s.c_str());
  if (!r.ok) {
    std::fprintf(stderr, "offline_radar_slam: %s\n", r.error.c_str());
    return 1;
  }
  std::error_code ec;
  std::filesystem::create_directories(output, ec);
  std::string error;
  const std::string out = output + "/";
  if (!writeTumTrajectory(out + "odometry_tum.txt", r.odometry, &error) ||
      !writeTumTrajectory(out + "trajectory_tum.txt", r.trajectory, &error) ||
      (!r.ground_truth.empty() &&
       !writeTumTrajectory(out + "ground_truth_tum.txt", r.ground_truth, &error))) {
    std::fprintf(stderr, "offline_radar_slam: %s\n", error.c_str());
    return 1;
  }
  std::vector<std::pair<double, double>> loop_errors;  // per loop, when there is ground truth
  const nlohmann::json j = radarReport(r, slam_params, mulran, wall_s, &loop_errors);
  writeFileAtomically(out + "timing.json", j.dump(2) + "\n", nullptr);
  writeFileAtomically(out + "loops.csv", loopsCsv(r.loops, loop_errors), nullptr);
  if (json)
    std::printf("%s\n", j.dump(2).c_str());
  else
    printReport(r, j);
  return 0;
}
