// radar_benchmark: radar odometry on real Oxford Radar RobotCar scans against the dataset's
// radar-odometry ground truth, pair by pair, with the time per stage and the ratio to real time
// (4 Hz). Options override config/radar.yaml (see doc/radar.md).
#include <cstdio>
#include <cstring>
#include <string>

#include "osm_graph_slam/eval/radar_evaluation.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

int main(int argc, char** argv) {
  std::string dir = "../shared/data/oxford_radar", config, gt;
  radar::RadarOdometryParams params;
  std::string detector, beta, mc;
  tools::CommandLine cli("radar_benchmark",
                         "Radar odometry on real Oxford Radar RobotCar scans against the "
                         "dataset's radar-odometry ground truth, pair by pair, with the time per "
                         "stage. Options override config/radar.yaml (see doc/radar.md).");
  cli.option("--oxford", "DIR", "the Oxford radar scans", &dir)
      .option("--ground-truth", "CSV", "the radar odometry ground truth", &gt)
      .defaultText("DIR/radar_odometry.csv")
      .option("--config", "YAML", "radar parameters", &config)
      .option("--detector", "kstrongest|cfar", "the feature detector", &detector)
      .option("--beta", "S", "the Doppler beta (0: no Doppler correction)",
              [&beta](const std::string& v) {
                double b = 0.0;
                if (!tools::parseDouble(v, &b)) return "'" + v + "' is not a number";
                beta = v;
                return std::string();
              })
      .option("--motion-compensation", "0|1", "motion compensation off or on", &mc);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (!config.empty()) {
    const YamlParamReader yaml = YamlParamReader::fromFile(config);
    std::string error;
    if (!yaml.ok() || !radar::readParams(yaml, params, &error)) {
      std::fprintf(stderr, "radar_benchmark: %s\n",
                   yaml.ok() ? error.c_str() : yaml.error().c_str());
      return 2;
    }
  }
  if (!detector.empty()) params.features.detector = detector;
  if (!beta.empty()) {
    params.motion.doppler_beta = std::stod(beta);
    params.motion.doppler_correction = params.motion.doppler_beta != 0.0;
  }
  if (!mc.empty()) params.motion.motion_compensation = mc != "0";
  if (gt.empty()) gt = dir + "/radar_odometry.csv";
  const radar::OxfordEvaluation ev = radar::evaluateOxfordDrive(dir, gt, params);
  if (!ev.ok) {
    std::fprintf(stderr, "radar_benchmark: %s\n", ev.error.c_str());
    return 1;
  }
  std::printf("detector %s, motion compensation %d, doppler beta %.4f s\n",
              params.features.detector.c_str(), params.motion.motion_compensation,
              params.motion.doppler_correction ? params.motion.doppler_beta : 0.0);
  std::printf(
      "pair  gt_x    gt_y    gt_yaw   est_x   est_y   est_yaw  t_err  r_err  feat match inl"
      "  ms_feat ms_match ms_motion\n");
  double ms_f = 0, ms_m = 0, ms_r = 0;
  for (size_t k = 0; k < ev.pairs.size(); ++k) {
    const auto& e = ev.pairs[k];
    std::printf(
        "%2zu  %6.3f %7.3f %7.3f  %6.3f %7.3f %7.3f  %5.3f %6.3f %4d %5d %4d  %7.1f %7.1f "
        "%8.1f%s\n",
        k, e.gt_x, e.gt_y, e.gt_yaw * 180 / M_PI, e.est_x, e.est_y, e.est_yaw * 180 / M_PI,
        e.translation_error, e.rotation_error * 180 / M_PI, e.features, e.matches, e.inliers,
        e.ms_features, e.ms_matching, e.ms_motion,
        e.estimated ? "" : "  (failed: constant velocity)");
    ms_f += e.ms_features;
    ms_m += e.ms_matching;
    ms_r += e.ms_motion;
  }
  const double n = double(ev.pairs.size());
  const double ms_total = (ms_f + ms_m + ms_r) / n;
  std::printf("pairs %zu, ground truth %.2f m\n", ev.pairs.size(), ev.gt_length);
  std::printf(
      "translation error mean %.3f m max %.3f m; rotation error mean %.3f deg max %.3f deg\n",
      ev.mean_translation_error, ev.max_translation_error, ev.mean_rotation_error_deg,
      ev.max_rotation_error_deg);
  std::printf("drift: chained end point %.2f %%, mean per pair %.2f %%\n", ev.drift_percent,
              ev.mean_pair_drift_percent);
  std::printf(
      "time per scan: features %.1f ms, matching %.1f ms, motion %.1f ms, total %.1f ms = "
      "%.2fx real time at 4 Hz (250 ms)\n",
      ms_f / n, ms_m / n, ms_r / n, ms_total, 250.0 / ms_total);
  if (!ev.error.empty())
    std::fprintf(stderr, "radar_benchmark: scans skipped:\n%s", ev.error.c_str());
  return 0;
}
