// offline_localization: localisation on a saved map package (written by offline_slam) for a KITTI
// raw drive folder or a bag, without a ROS master, as fast as the CPU allows.
//
// The options: offline_localization --help.
//
// The map frame is the map package's ENU origin; the drive's own origin (its first fix) is
// carried over through lat/lon. Without --initial-pose or --global the first GNSS fix and the IMU
// heading start the filter. The drive's GNSS fixes check the tracked pose and global answers
// (gnss_check_distance; never a correction) unless --no-gnss. Global localisation also searches
// the map package's buildings with the scan's walls (global_osm_walls) unless --no-osm-walls.
// Writes trajectory_tum.txt (every
// localised scan, map frame), ground_truth_tum.txt (the truth at the same stamps),
// off_map_tum.txt (flagged scans, predicted only), status.csv (per scan), timing.json /
// timing.txt; --json prints the report.
// --map-truth: the ground truth of the map's keyframes (offline_slam's ground_truth_tum.txt): the
// report then also gives the error relative to the map (the truth moved by the rigid transform
// that best aligns the map's keyframes to their truth), which separates the localiser's error
// from the map's own absolute error (a simulated map is off by its GNSS origin).
// --kidnap-at N: the vehicle is carried off at drive scan N to where it is kidnap-distance (50 m)
// away (the scans in between are skipped, the time continues): the report gives the drive time
// until the divergence was detected and until a correct re-localisation.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/drive_io/drive_source.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/localization/map_frames.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "support/command_line.h"
#include "support/drive_options.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double yawOfPose(const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d x = pose.linear().col(0);
  return std::atan2(x.y(), x.x());
}

/// Every place a global attempt registered, with its error against the truth when known.
void logGlobalAttempt(std::ostringstream& log, double stamp, const GlobalLocalizationResult& g,
                      const std::optional<Eigen::Isometry3d>& truth) {
  if (g.candidates.empty())
    log << stamp << ' ' << (g.success ? "success" : "failure") << " - - - none - - - - - - - - -\n";
  for (const GlobalCandidate& c : g.candidates) {
    double e = std::nan(""), yaw_error = std::nan("");
    if (truth) {
      e = (c.pose.translation() - truth->translation()).head<2>().norm();
      yaw_error =
          Eigen::AngleAxisd(truth->linear().transpose() * c.pose.linear()).angle() * 180 / M_PI;
    }
    log << stamp << ' ' << (g.success ? "success" : "failure") << ' ' << c.keyframe_id << ' '
        << c.source << ' ' << c.descriptor_distance << ' ' << c.outcome << ' ' << c.fitness << ' '
        << c.overlap << ' ' << c.structure_overlap << ' ' << c.pose.translation().x() << ' '
        << c.pose.translation().y() << ' ' << yawOfPose(c.pose) << ' ' << e << ' ' << yaw_error
        << ' ' << c.structure_cost << ' ' << c.wall_fitness << '\n';
  }
}

struct RunErrors {
  size_t n = 0;
  double sum_t = 0, max_t = 0, sum_yaw = 0, max_yaw = 0, sum_t2 = 0;
  void add(double t, double yaw) {
    ++n;
    sum_t += t;
    sum_t2 += t * t;
    max_t = std::max(max_t, t);
    sum_yaw += yaw;
    max_yaw = std::max(max_yaw, yaw);
  }
  std::string json() const {
    std::ostringstream o;
    o << std::setprecision(6) << "{\"scans\": " << n
      << ", \"translation_mean_m\": " << (n ? sum_t / n : 0.0)
      << ", \"translation_rmse_m\": " << (n ? std::sqrt(sum_t2 / n) : 0.0)
      << ", \"translation_max_m\": " << max_t
      << ", \"heading_mean_deg\": " << (n ? sum_yaw / n : 0.0) * 180.0 / M_PI
      << ", \"heading_max_deg\": " << max_yaw * 180.0 / M_PI << "}";
    return o.str();
  }
};

/// The command line: switches and values (the drive stays text for openDriveSource()).
struct Options {
  bool json = false, use_imu = true, use_gnss = true, global = false, osm_walls = true;
  size_t start_scan = 0, max_scans = std::numeric_limits<size_t>::max();
  int kidnap_at = -1;
  double kidnap_distance = 50.0;
  std::string map, output, config, map_truth, initial_pose;
};

void declareOptions(CommandLine& cli, Options& o) {
  cli.option("--map", "DIR", "the map package (offline_slam's OUT/map_package)", &o.map)
      .required()
      .option("--output", "DIR", "where the trajectories, status.csv and the report go", &o.output)
      .required();
  tools::addDriveSourceOptions(cli);
  cli.option("--initial-pose", "x,y,yaw|truth",
             "the first pose (map frame, m and rad) or the drive's ground truth; default: the "
             "first GNSS fix and the IMU heading",
             &o.initial_pose)
      .flag("--global", "start by global localisation", &o.global)
      .option("--config", "OVERRIDES.yaml",
              "pipeline overrides and a \"localization\" block over config/localization*.yaml",
              &o.config)
      .option("--max-scans", "N", "localise at most N scans after --start-scan", &o.max_scans)
      .defaultText("all")
      .option("--start-scan", "N", "skip the drive's first N scans", &o.start_scan)
      .flag("--no-imu", "no IMU rates for the motion prediction", &o.use_imu, false)
      .flag("--no-gnss", "no GNSS checks of the tracked pose and global answers", &o.use_gnss,
            false)
      .flag("--no-osm-walls", "global localisation without the map package's buildings",
            &o.osm_walls, false)
      .option("--map-truth", "GT_TUM",
              "the ground truth of the map's keyframes (offline_slam's ground_truth_tum.txt): "
              "errors also relative to the map",
              &o.map_truth)
      .option("--kidnap-at", "N", "carry the vehicle off at drive scan N", &o.kidnap_at)
      .defaultText("none")
      .option("--kidnap-distance", "M", "how far the vehicle is carried off", &o.kidnap_distance)
      .flag("--json", "print the report as JSON", &o.json)
      .note(
          "--initial-pose and --global exclude each other; --scans drives are not supported "
          "(no per-scan time base).");
}

/// Pipeline parameters (the prefilter as the SLAM pipeline has it) and the localiser's.
bool loadParams(const std::string& config_dir, const std::string& overrides_file,
                SlamPipelineParams& pipeline, LocalizationParams& params, std::string* error) {
  return loadPipelineParams(config_dir, overrides_file, pipeline, error) &&
         loadLocalizationParams(config_dir, overrides_file, params, error);
}

/// Map frame -> truth frame, from the map's keyframes and their ground truth (--map-truth).
bool alignMapToTruth(const std::string& path, const MapPackage& map,
                     Eigen::Isometry3d* truth_to_map, std::string* error) {
  const TrajectoryReadResult gt = readTrajectory(path);
  if (!gt.ok) {
    *error = "--map-truth: " + gt.error;
    return false;
  }
  std::map<long long, Eigen::Vector3d> by_stamp;
  for (const auto& sp : gt.trajectory)
    by_stamp[std::llround(sp.stamp * 1e3)] = sp.pose.translation();
  std::vector<Eigen::Vector3d> a, b;
  for (const auto& kf : map.keyframes) {
    const auto it = by_stamp.find(std::llround(kf.stamp * 1e3));
    if (it == by_stamp.end()) continue;
    b.push_back(kf.pose.translation());
    a.push_back(it->second);
  }
  if (a.size() < 3) {
    *error = "--map-truth matches only " + std::to_string(a.size()) + " keyframes of the map";
    return false;
  }
  *truth_to_map = alignUmeyama(a, b);
  return true;
}

bool parseXyYaw(const std::string& text, double* x, double* y, double* yaw) {
  char c1, c2;
  std::istringstream is(text);
  return (is >> *x >> c1 >> *y >> c2 >> *yaw) && c1 == ',' && c2 == ',';
}

/// Kidnapping (--kidnap-at N): from drive scan N on, the scans are skipped until the vehicle is
/// --kidnap-distance (50 m) from where it was (straight line, by the truth); later stamps are
/// shifted back by the skipped time, so the filter sees a continuous drive whose pose jumped.
struct Kidnap {
  /// Where the vehicle landed counts as on the map within this distance of a map keyframe (a
  /// landing off the mapped path cannot be re-localised before).
  static constexpr double kOnMap = 10.0;
  long at = -1;
  double distance = 50.0;
  bool kidnapping = false, kidnapped = false;
  Eigen::Vector3d from = Eigen::Vector3d::Zero();
  double stamp = 0.0, time_shift = 0.0, jump = 0.0;
  double detected_s = -1.0, recovered_s = -1.0;
  size_t skipped = 0;
  bool recovered_correct = false;
  double landing_distance = -1.0, on_map_s = -1.0;
};

/// What the run counted, scan by scan, for the outputs and the report.
struct LocalizationRun {
  Trajectory estimate, truth_at_estimate, off_map;
  std::ostringstream status_csv, global_log;
  RunErrors tracking_error, all_error, tracking_error_map, all_error_map;
  size_t scans = 0, first_localized = 0, skipped = 0, wrong_relocalizations = 0;
  bool localized_once = false, last_relocalization_correct = false;
  double prefilter_ms = 0, localize_ms = 0, input_ms = 0, load_ms = 0, init_ms = 0, wall_s = 0;
  bool prefilter_ahead = true;
  size_t wall_buildings = 0;
  Kidnap kidnap;

  LocalizationRun() {
    status_csv << std::setprecision(15)
               << "# stamp status fitness distance_to_map_m x y yaw error_m error_yaw_deg\n";
    global_log << std::setprecision(15)
               << "# stamp result keyframe source descriptor_distance outcome fitness overlap "
                  "structure_overlap x y yaw "
                  "error_m error_yaw_deg structure_cost wall_fitness (one line per place tried; "
                  "result: the "
                  "attempt's answer)\n";
  }
};

/// Whether drive scan i is skipped by the kidnapping; shifts the stamps after it. Exit status 1
/// when the drive has no truth to kidnap by.
std::optional<int> kidnapStep(Kidnap& k, size_t i, size_t n, DriveScan& scan, bool* skip) {
  *skip = false;
  if (k.at >= 0 && !k.kidnapped && !k.kidnapping && static_cast<long>(i) == k.at) {
    if (!scan.truth) {
      std::cerr << "offline_localization: --kidnap-at needs a drive with ground truth\n";
      return 1;
    }
    k.kidnapping = true;
    k.from = scan.truth->translation();
    k.stamp = scan.stamp;
  }
  if (k.kidnapping) {
    k.jump = scan.truth ? (scan.truth->translation() - k.from).head<2>().norm() : 0.0;
    if (k.jump < k.distance) {
      ++k.skipped;
      printProgress(i + 1, n);
      *skip = true;
      return std::nullopt;
    }
    k.kidnapping = false;
    k.kidnapped = true;
    k.time_shift = scan.stamp - k.stamp;
  }
  scan.stamp -= k.time_shift;
  return std::nullopt;
}

/// The filter's start at the first scan: --initial-pose (x,y,yaw or truth), else the first GNSS
/// fix and IMU heading unless --global. Exit status 1 when the start cannot be had.
std::optional<int> startLocalizer(Localizer& localizer, const Options& opt, const MapPackage& map,
                                  const DriveScan& scan,
                                  const std::optional<Eigen::Isometry3d>& truth,
                                  const std::optional<Eigen::Isometry3d>& truth_to_map,
                                  const Eigen::Isometry3d& drive_to_map) {
  const std::string& initial = opt.initial_pose;
  if (initial == "truth") {
    if (!truth) {
      std::cerr << "offline_localization: --initial-pose truth: the drive has no ground truth\n";
      return 1;
    }
    // Where the vehicle is on the map: with --map-truth, past the map's own absolute error.
    localizer.setInitialPose(truth_to_map ? *truth_to_map * *truth : *truth, scan.stamp);
  } else if (!initial.empty()) {
    double x, y, yaw;
    parseXyYaw(initial, &x, &y, &yaw);
    localizer.setInitialPose(mapPoseFromXyYaw(map, x, y, yaw), scan.stamp);
  } else if (!opt.global) {
    if (!scan.gnss || !scan.orientation) {
      std::cerr << "offline_localization: the first scan has no GNSS fix and IMU orientation; "
                   "use --initial-pose or --global\n";
      return 1;
    }
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = scan.orientation->toRotationMatrix();
    pose.translation() = Eigen::Vector3d(scan.gnss->x(), scan.gnss->y(), 0.0);
    pose = drive_to_map * pose;
    pose.translation().z() = mapHeightAt(map, pose.translation());
    localizer.setInitialPose(pose, scan.stamp);
  }
  return std::nullopt;
}

/// One localised scan in the run's trajectories, errors, kidnap times and status.csv.
void recordScan(LocalizationRun& run, const Localizer& localizer, const DriveScan& scan,
                const LocalizationOutput& out, const std::optional<Eigen::Isometry3d>& truth,
                const std::optional<Eigen::Isometry3d>& truth_to_map) {
  double err_t = std::nan(""), err_yaw = std::nan("");
  if (truth) {
    err_t = (out.pose.translation() - truth->translation()).head<2>().norm();
    err_yaw = Eigen::AngleAxisd(truth->linear().transpose() * out.pose.linear()).angle();
  }
  const bool localized = out.status == LocalizationStatus::kTracking ||
                         out.status == LocalizationStatus::kPredicted ||
                         out.status == LocalizationStatus::kRelocalized;
  if (localized) {
    if (!run.localized_once) run.first_localized = run.scans;
    run.localized_once = true;
    run.estimate.push_back({scan.stamp, out.pose});
    if (truth) {
      run.truth_at_estimate.push_back({scan.stamp, *truth});
      run.all_error.add(err_t, err_yaw);
      if (out.status == LocalizationStatus::kTracking) run.tracking_error.add(err_t, err_yaw);
      if (truth_to_map) {
        const Eigen::Isometry3d t = *truth_to_map * *truth;
        const double e = (out.pose.translation() - t.translation()).head<2>().norm();
        const double y = Eigen::AngleAxisd(t.linear().transpose() * out.pose.linear()).angle();
        run.all_error_map.add(e, y);
        if (out.status == LocalizationStatus::kTracking) run.tracking_error_map.add(e, y);
      }
      // A re-localisation is wrong beyond 0.5 m or 2 deg (relative to the map when its truth
      // is known: the map itself may be off by its GNSS origin).
      double check_t = err_t, check_yaw = err_yaw;
      if (truth_to_map) {
        const Eigen::Isometry3d t = *truth_to_map * *truth;
        check_t = (out.pose.translation() - t.translation()).head<2>().norm();
        check_yaw = Eigen::AngleAxisd(t.linear().transpose() * out.pose.linear()).angle();
      }
      if (out.status == LocalizationStatus::kRelocalized) {
        run.last_relocalization_correct = check_t <= 0.5 && check_yaw <= 2.0 * M_PI / 180;
        if (!run.last_relocalization_correct) ++run.wrong_relocalizations;
      }
    }
  } else if (out.status == LocalizationStatus::kOffMap) {
    run.off_map.push_back({scan.stamp, out.pose});
  }
  Kidnap& k = run.kidnap;
  if (k.kidnapped) {
    if (truth && k.on_map_s < 0.0) {
      const double d =
          localizer.distanceToMap((truth_to_map ? *truth_to_map * *truth : *truth).translation());
      if (k.landing_distance < 0.0) k.landing_distance = d;
      if (d <= Kidnap::kOnMap) k.on_map_s = scan.stamp - k.stamp;
    }
    if (out.diverged && k.detected_s < 0.0) k.detected_s = scan.stamp - k.stamp;
    if (out.status == LocalizationStatus::kRelocalized && k.detected_s >= 0.0 &&
        k.recovered_s < 0.0) {
      k.recovered_s = scan.stamp - k.stamp;
      k.recovered_correct = run.last_relocalization_correct;
    }
  }
  run.status_csv << scan.stamp << ' ' << toString(out.status) << ' ' << out.fitness << ' '
                 << out.distance_to_map << ' ' << out.pose.translation().x() << ' '
                 << out.pose.translation().y() << ' ' << yawOfPose(out.pose) << ' ' << err_t << ' '
                 << err_yaw * 180.0 / M_PI << '\n';
}

/// The report as JSON (timing.json, --json).
std::string reportJson(const LocalizationRun& run, const LocalizationStats& s, const Options& opt) {
  const size_t scans = run.scans;
  const double wall_s = run.wall_s, per_scan = scans ? 1.0 / scans : 0.0;
  const Kidnap& k = run.kidnap;
  std::ostringstream j;
  j << std::setprecision(6) << "{\"map\": \"" << opt.map << "\", \"scans\": " << scans
    << ", \"skipped\": " << run.skipped << ", \"localized\": " << run.estimate.size()
    << ", \"tracking\": " << s.tracking << ", \"predicted\": " << s.predicted
    << ", \"off_map\": " << s.off_map << ", \"off_map_odometry\": " << s.off_map_odometry
    << ", \"not_localized\": " << s.uninitialized << ", \"relocalized\": " << s.relocalizations
    << ", \"divergences\": " << s.divergences << ", \"global_attempts\": " << s.global_attempts
    << ", \"global_failures\": " << s.global_failures
    << ", \"global_by_side_view\": " << s.global_by_side_view
    << ", \"osm_wall_buildings\": " << run.wall_buildings
    << ", \"global_osm_searches\": " << s.global_osm_searches
    << ", \"global_by_osm_walls\": " << s.global_by_osm_walls
    << ", \"global_osm_ms\": " << s.global_osm_ms
    << ", \"gnss_used\": " << (opt.use_gnss ? "true" : "false")
    << ", \"gnss_divergences\": " << s.gnss_divergences
    << ", \"global_gnss_refusals\": " << s.global_gnss_refusals

    << ", \"global_descriptor_limit\": " << s.global_descriptor_limit
    << ", \"global_impostor_pairs\": " << s.global_impostor_pairs
    << ", \"global_overlap_limit\": " << s.global_overlap_limit
    << ", \"global_overlap_learning\": {\"own_places\": " << s.global_overlap_own
    << ", \"impostors_passing_fitness\": " << s.global_overlap_impostors
    << ", \"own_low\": " << s.global_overlap_own_low
    << ", \"impostor_high\": " << s.global_overlap_impostor_high
    << ", \"ms\": " << s.global_overlap_learn_ms << "}"
    << ", \"first_localized_scan\": " << (run.localized_once ? long(run.first_localized) : -1L)
    << ", \"wrong_relocalizations\": " << run.wrong_relocalizations;
  if (k.at >= 0)
    j << ", \"kidnap\": {\"at_scan\": " << k.at << ", \"jump_m\": " << k.jump
      << ", \"skipped_scans\": " << k.skipped
      << ", \"landing_distance_to_map_m\": " << k.landing_distance
      << ", \"within_10m_of_map_after_s\": " << k.on_map_s
      << ", \"detected_after_s\": " << k.detected_s << ", \"recovered_after_s\": " << k.recovered_s
      << ", \"recovered_correct\": " << (k.recovered_correct ? "true" : "false") << "}";
  j << ", \"error_tracking\": " << run.tracking_error.json()
    << ", \"error_all\": " << run.all_error.json()
    << ", \"error_tracking_vs_map\": " << run.tracking_error_map.json()
    << ", \"error_all_vs_map\": " << run.all_error_map.json()
    << ", \"timing\": {\"wall_s\": " << wall_s
    << ", \"scans_per_s\": " << (wall_s > 0 ? scans / wall_s : 0.0)
    << ", \"real_time_factor\": " << (wall_s > 0 ? scans / wall_s / 10.0 : 0.0)
    << ", \"map_load_ms\": " << run.load_ms << ", \"localizer_init_ms\": " << run.init_ms
    << ", \"input_ms_per_scan\": " << run.input_ms * per_scan
    << ", \"prefilter_ms_per_scan\": " << run.prefilter_ms * per_scan
    << ", \"prefilter_ahead\": " << (run.prefilter_ahead ? "true" : "false")
    << ", \"localize_ms_per_scan\": " << run.localize_ms * per_scan
    << ", \"registration_ms_per_scan\": " << s.registration_ms * per_scan
    << ", \"local_map_ms_per_scan\": " << s.local_map_ms * per_scan
    << ", \"local_map_builds\": " << s.local_map_builds << ", \"global_ms_total\": " << s.global_ms
    << ", \"global_ms_per_attempt\": " << (s.global_attempts ? s.global_ms / s.global_attempts : 0)
    << ", \"filter_ms_per_scan\": " << s.filter_ms * per_scan << "}}";
  return j.str();
}

/// The report as text (timing.txt, stdout).
std::string reportTable(const LocalizationRun& run, const LocalizationStats& s,
                        const MapPackage& map) {
  const size_t scans = run.scans;
  const double wall_s = run.wall_s, per_scan = scans ? 1.0 / scans : 0.0;
  const Kidnap& k = run.kidnap;
  const RunErrors &tracking_error = run.tracking_error,
                  &tracking_error_map = run.tracking_error_map;
  std::ostringstream table;
  table << std::fixed << std::setprecision(2) << "offline_localization: " << scans << " scans in "
        << wall_s << " s (" << (wall_s > 0 ? scans / wall_s : 0.0) << " scans/s, x"
        << (wall_s > 0 ? scans / wall_s / 10.0 : 0.0) << " real time)\n"
        << "  localized " << run.estimate.size() << " (tracking " << s.tracking << ", predicted "
        << s.predicted << ", re-localized " << s.relocalizations << "), off map " << s.off_map
        << " (" << s.off_map_odometry << " carried by scan-to-scan registration)"
        << ", not localized " << s.uninitialized << ", divergences " << s.divergences << "\n"
        << "  per scan [ms]: input " << run.input_ms * per_scan << ", prefilter "
        << (run.prefilter_ahead ? "(ahead, on the reading thread) " : "")
        << run.prefilter_ms * per_scan << ", localize " << run.localize_ms * per_scan
        << " (registration " << s.registration_ms * per_scan << ", local map "
        << s.local_map_ms * per_scan << " over " << s.local_map_builds << " builds, filter "
        << s.filter_ms * per_scan << ")\n"
        << "  global localisation: " << s.global_attempts << " attempts, " << s.global_failures
        << " failed, " << (s.global_attempts ? s.global_ms / s.global_attempts : 0.0)
        << " ms each; Scan Context limit " << s.global_descriptor_limit << " (from "
        << s.global_impostor_pairs << " pairs of different places); overlap limit "
        << s.global_overlap_limit << " (own places " << s.global_overlap_own_low << " over "
        << s.global_overlap_own << ", impostors " << s.global_overlap_impostor_high << " over "
        << s.global_overlap_impostors << ", learnt in " << s.global_overlap_learn_ms << " ms)\n"
        << "  map: " << map.keyframes.size() << " keyframes, " << map.map_cloud->size()
        << " points (loaded in " << run.load_ms << " ms, localizer ready in " << run.init_ms
        << " ms)\n";
  if (k.at >= 0)
    table << std::setprecision(2) << "  kidnap at scan " << k.at << " (" << k.jump << " m, "
          << k.skipped << " scans skipped, landed " << k.landing_distance
          << " m from the map, within " << Kidnap::kOnMap << " m of it after " << k.on_map_s
          << " s): detected after " << k.detected_s << " s, re-localised after " << k.recovered_s
          << " s of drive (" << (k.recovered_correct ? "correct" : "WRONG or none") << ")\n";
  if (tracking_error.n)
    table << std::setprecision(3) << "  error while tracking: mean "
          << tracking_error.sum_t / tracking_error.n << " m, max " << tracking_error.max_t
          << " m; heading mean " << tracking_error.sum_yaw / tracking_error.n * 180 / M_PI
          << " deg, max " << tracking_error.max_yaw * 180 / M_PI << " deg\n";
  if (tracking_error_map.n)
    table << std::setprecision(3) << "  error relative to the map: mean "
          << tracking_error_map.sum_t / tracking_error_map.n << " m, max "
          << tracking_error_map.max_t << " m; heading mean "
          << tracking_error_map.sum_yaw / tracking_error_map.n * 180 / M_PI << " deg, max "
          << tracking_error_map.max_yaw * 180 / M_PI << " deg\n";
  return table.str();
}

/// The run's files in the output folder; false with the reason in error.
bool writeOutputs(const LocalizationRun& run, const std::string& out_dir, const std::string& json,
                  const std::string& table, std::string* error) {
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  bool ok = writeTumTrajectory(out_dir + "/trajectory_tum.txt", run.estimate, error);
  ok = ok && writeTumTrajectory(out_dir + "/ground_truth_tum.txt", run.truth_at_estimate, error);
  ok = ok && writeTumTrajectory(out_dir + "/off_map_tum.txt", run.off_map, error);
  ok = ok && writeFileAtomically(out_dir + "/status.csv", run.status_csv.str(), error);
  ok = ok && writeFileAtomically(out_dir + "/global_attempts.csv", run.global_log.str(), error);
  ok = ok && writeFileAtomically(out_dir + "/timing.json", json + "\n", error);
  ok = ok && writeFileAtomically(out_dir + "/timing.txt", table, error);
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  reuseFreedMemory();  // scan-sized buffers stay in the heap (common/memory_tuning.h)
  Options opt;
  CommandLine cli("offline_localization",
                  "Localisation on a saved map package (written by offline_slam) for a KITTI raw "
                  "drive folder or a bag, without a ROS master, as fast as the CPU allows.");
  declareOptions(cli, opt);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  const std::map<std::string, std::string> args = cli.values();
  if (cli.has("--scans"))
    return cli.fail("--scans drives are not supported (no per-scan time base)");
  if (opt.global && cli.has("--initial-pose"))
    return cli.fail("--initial-pose and --global exclude each other");

  std::string error;
  LocalizationRun run;
  auto map = std::make_shared<MapPackage>();
  const auto t_load = Clock::now();
  if (!loadMapPackage(opt.map, *map, &error)) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }
  run.load_ms = msSince(t_load);
  if (!map->has_origin) {
    std::cerr << "offline_localization: the map package has no ENU origin\n";
    return 1;
  }

  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  SlamPipelineParams pipeline;
  LocalizationParams params;
  if (!loadParams(config_dir, opt.config, pipeline, params, &error)) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }

  const std::unique_ptr<DriveSource> drive = openDriveSource(args, "offline_localization", &error);
  if (!drive) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }
  pipeline.prefilter.sensor_to_base = drive->sensor_to_base;
  params.sensor_to_base = drive->sensor_to_base;  // deskewing: azimuths about the LiDAR
  CloudPrefilter prefilter(pipeline.prefilter);
  const EnuConverter drive_enu(drive->lat, drive->lon, drive->alt);
  const EnuConverter map_enu(map->origin_lat, map->origin_lon, map->origin_alt);
  const Eigen::Isometry3d drive_to_map = enuToEnu(drive_enu, map_enu);

  std::optional<Eigen::Isometry3d> truth_to_map;
  if (!opt.map_truth.empty()) {
    Eigen::Isometry3d aligned;
    if (!alignMapToTruth(opt.map_truth, *map, &aligned, &error)) {
      std::cerr << "offline_localization: " << error << "\n";
      return 1;
    }
    truth_to_map = aligned;
  }

  const auto t_init = Clock::now();
  Localizer localizer(params, map);
  run.wall_buildings = opt.osm_walls ? localizer.enableOsmWalls(pipeline.wall, pipeline.segments,
                                                                pipeline.backend.matcher)
                                     : 0;
  run.init_ms = msSince(t_init);

  double x, y, yaw;
  if (!opt.initial_pose.empty() && opt.initial_pose != "truth" &&
      !parseXyYaw(opt.initial_pose, &x, &y, &yaw))
    return cli.fail("--initial-pose takes x,y,yaw (map frame, m and rad) or truth");

  const size_t start = opt.start_scan;
  size_t n = drive->size();
  if (cli.has("--max-scans")) n = std::min<size_t>(n, start + opt.max_scans);
  // The prefilter runs on the reading thread, overlapping the localisation of the scans before
  // (as in offline_slam); scans skipped by --start-scan are not worth filtering.
  run.prefilter_ahead = start == 0;
  ScanPrefetcher::Prepare prefilter_step;
  if (run.prefilter_ahead)
    prefilter_step = [&prefilter](DriveScan& s) {
      s.filtered = prefilter.filter(*s.cloud);
      s.cloud.reset();
    };
  ScanPrefetcher prefetcher(*drive, n, 8, prefilter_step);
  run.kidnap.at = opt.kidnap_at;
  run.kidnap.distance = opt.kidnap_distance;
  bool started = false;
  DriveScan scan;
  const auto t_run = Clock::now();
  for (size_t i = 0; i < n; ++i) {
    auto t0 = Clock::now();
    if (!prefetcher.next(scan)) break;
    run.input_ms += msSince(t0);
    if (i < start) continue;
    bool skip = false;
    if (const auto exit_code = kidnapStep(run.kidnap, i, n, scan, &skip)) return *exit_code;
    if (skip) continue;
    if (!scan.cloud && !scan.filtered) {
      std::cerr << "\noffline_localization: " << scan.error << " (scan skipped)\n";
      ++run.skipped;
      continue;
    }
    ++run.scans;
    std::optional<Eigen::Isometry3d> truth;
    if (scan.truth) truth = drive_to_map * *scan.truth;
    if (!started) {
      started = true;
      if (const auto exit_code =
              startLocalizer(localizer, opt, *map, scan, truth, truth_to_map, drive_to_map))
        return *exit_code;
    }
    t0 = Clock::now();
    const CloudPrefilterResult filtered =
        scan.filtered ? std::move(*scan.filtered) : prefilter.filter(*scan.cloud);
    run.prefilter_ms += scan.filtered ? scan.prepare_ms : msSince(t0);
    const size_t global_attempts_before = localizer.stats().global_attempts;
    if (opt.use_gnss && scan.gnss)
      localizer.setGnssFix(
          scan.stamp,
          (drive_to_map * Eigen::Vector3d(scan.gnss->x(), scan.gnss->y(), 0.0)).head<2>(),
          scan.gnss_std.value_or(0.0));
    t0 = Clock::now();
    const LocalizationOutput out =
        opt.use_imu ? localizer.process(scan.stamp, filtered.cloud, scan.angular_velocity,
                                        scan.linear_acceleration)
                    : localizer.process(scan.stamp, filtered.cloud);
    run.localize_ms += msSince(t0);
    if (localizer.stats().global_attempts > global_attempts_before)
      logGlobalAttempt(
          run.global_log, scan.stamp, localizer.lastGlobal(),
          truth && truth_to_map ? std::optional<Eigen::Isometry3d>(*truth_to_map * *truth) : truth);
    recordScan(run, localizer, scan, out, truth, truth_to_map);
    printProgress(i + 1, n);
  }
  run.wall_s = msSince(t_run) / 1000.0;

  const std::string json = reportJson(run, localizer.stats(), opt);
  const std::string table = reportTable(run, localizer.stats(), *map);
  if (!writeOutputs(run, opt.output, json, table, &error)) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }
  std::cout << (opt.json ? json + "\n" : table);
  return 0;
}
