// offline_localization: localisation on a saved map package (written by offline_slam) for a KITTI
// raw drive folder or a bag, without a ROS master, as fast as the CPU allows.
//
//   offline_localization --map DIR (--kitti-raw DRIVE_DIR [--calib-dir DIR] | --bag FILE.bag)
//                        --output DIR [--initial-pose x,y,yaw | --initial-pose truth | --global]
//                        [--config OVERRIDES.yaml] [--max-scans N] [--start-scan N] [--no-imu]
//                        [--no-gnss] [--no-osm-walls]
//                        [--map-truth GT_TUM] [--kidnap-at N [--kidnap-distance M]] [--json]
//                        [--cloud-topic T ...]   (bag topics as offline_slam)
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
#include <sstream>
#include <string>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/drive_io/drive_source.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/localization/map_frames.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

int usage(const std::string& why) {
  std::cerr << "offline_localization: " << why << "\n"
            << "usage: offline_localization --map DIR (--kitti-raw DRIVE_DIR [--calib-dir DIR]\n"
               "       | --bag FILE.bag) --output DIR\n"
               "       [--initial-pose x,y,yaw | --initial-pose truth | --global]\n"
               "       [--config OVERRIDES.yaml] [--max-scans N] [--start-scan N] [--no-imu] "
               "[--no-gnss] [--no-osm-walls]\n"
               "       [--map-truth GT_TUM] [--kidnap-at N [--kidnap-distance M]] [--json]\n"
               "       [--cloud-topic T] [--gps-topic T]\n"
               "       [--imu-topic T]"
               "       [--ground-truth-topic T] [--base-frame F]\n";
  return 2;
}

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

}  // namespace

int main(int argc, char** argv) {
  reuseFreedMemory();  // scan-sized buffers stay in the heap (common/memory_tuning.h)
  std::map<std::string, std::string> args;
  bool json = false, use_imu = true, use_gnss = true, global = false, osm_walls = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--json") {
      json = true;
    } else if (a == "--no-imu") {
      use_imu = false;
    } else if (a == "--no-gnss") {
      use_gnss = false;
    } else if (a == "--no-osm-walls") {
      osm_walls = false;
    } else if (a == "--global") {
      global = true;
    } else if (a.rfind("--", 0) == 0 && i + 1 < argc) {
      args[a.substr(2)] = argv[++i];
    } else {
      return usage("unexpected argument '" + a + "'");
    }
  }
  if (!args.count("map")) return usage("--map is required");
  if (!args.count("output")) return usage("--output is required");
  if (args.count("scans")) return usage("--scans drives are not supported (no per-scan time base)");
  if (global && args.count("initial-pose"))
    return usage("--initial-pose and --global exclude each other");

  std::string error;
  auto map = std::make_shared<MapPackage>();
  const auto t_load = Clock::now();
  if (!loadMapPackage(args["map"], *map, &error)) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }
  const double load_ms = msSince(t_load);
  if (!map->has_origin) {
    std::cerr << "offline_localization: the map package has no ENU origin\n";
    return 1;
  }

  // Prefilter as the SLAM pipeline does (config/prefiltering.yaml); localisation parameters from
  // config/localization.yaml, then the override file's "localization" block.
  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  SlamPipelineParams pipeline;
  if (!loadPipelineParams(config_dir, args.count("config") ? args["config"] : "", pipeline,
                          &error)) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }
  LocalizationParams params;
  {
    const YamlParamReader defaults = YamlParamReader::fromFile(config_dir + "/localization.yaml");
    if (!defaults.ok()) {
      std::cerr << "offline_localization: " << defaults.error() << "\n";
      return 1;
    }
    readParams(defaults, params);
    if (args.count("config")) {
      const YamlParamReader overrides = YamlParamReader::fromFile(args["config"]);
      readParams(PrefixedParamReader(overrides, "localization"), params);
    }
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

  // Map frame -> truth frame, from the map's keyframes and their ground truth.
  std::optional<Eigen::Isometry3d> truth_to_map;
  if (args.count("map-truth")) {
    const TrajectoryReadResult gt = readTrajectory(args["map-truth"]);
    if (!gt.ok) {
      std::cerr << "offline_localization: --map-truth: " << gt.error << "\n";
      return 1;
    }
    std::map<long long, Eigen::Vector3d> by_stamp;
    for (const auto& sp : gt.trajectory)
      by_stamp[std::llround(sp.stamp * 1e3)] = sp.pose.translation();
    std::vector<Eigen::Vector3d> a, b;
    for (const auto& kf : map->keyframes) {
      const auto it = by_stamp.find(std::llround(kf.stamp * 1e3));
      if (it == by_stamp.end()) continue;
      b.push_back(kf.pose.translation());
      a.push_back(it->second);
    }
    if (a.size() < 3) {
      std::cerr << "offline_localization: --map-truth matches only " << a.size()
                << " keyframes of the map\n";
      return 1;
    }
    truth_to_map = alignUmeyama(a, b);
  }

  const auto t_init = Clock::now();
  Localizer localizer(params, map);
  const size_t wall_buildings =
      osm_walls
          ? localizer.enableOsmWalls(pipeline.wall, pipeline.segments, pipeline.backend.matcher)
          : 0;
  const double init_ms = msSince(t_init);

  std::string initial = args.count("initial-pose") ? args["initial-pose"] : "";
  if (!initial.empty() && initial != "truth") {
    double x, y, yaw;
    char c1, c2;
    std::istringstream is(initial);
    if (!(is >> x >> c1 >> y >> c2 >> yaw) || c1 != ',' || c2 != ',')
      return usage("--initial-pose takes x,y,yaw (map frame, m and rad) or truth");
  }

  const size_t start = args.count("start-scan") ? std::stoul(args["start-scan"]) : 0;
  size_t n = drive->size();
  if (args.count("max-scans")) n = std::min<size_t>(n, start + std::stoul(args["max-scans"]));
  // The prefilter runs on the reading thread, overlapping the localisation of the scans before
  // (as in offline_slam); scans skipped by --start-scan are not worth filtering.
  const bool prefilter_ahead = start == 0;
  ScanPrefetcher::Prepare prefilter_step;
  if (prefilter_ahead)
    prefilter_step = [&prefilter](DriveScan& s) {
      s.filtered = prefilter.filter(*s.cloud);
      s.cloud.reset();
    };
  ScanPrefetcher prefetcher(*drive, n, 8, prefilter_step);
  Trajectory estimate, truth_at_estimate, off_map;
  std::ostringstream status_csv;
  status_csv << std::setprecision(15)
             << "# stamp status fitness distance_to_map_m x y yaw error_m error_yaw_deg\n";
  RunErrors tracking_error, all_error, tracking_error_map, all_error_map;
  size_t scans = 0, first_localized = 0, skipped = 0;
  bool started = false, localized_once = false;
  double prefilter_ms = 0, localize_ms = 0, input_ms = 0;
  size_t wrong_relocalizations = 0;
  std::ostringstream global_log;
  global_log << std::setprecision(15)
             << "# stamp result keyframe source descriptor_distance outcome fitness overlap "
                "structure_overlap x y yaw "
                "error_m error_yaw_deg structure_cost wall_fitness (one line per place tried; "
                "result: the "
                "attempt's answer)\n";
  bool last_relocalization_correct = false;
  // Kidnapping (--kidnap-at N): from drive scan N on, the scans are skipped until the vehicle is
  // --kidnap-distance (50 m) from where it was (straight line, by the truth); later stamps are
  // shifted back by the skipped time, so the filter sees a continuous drive whose pose jumped.
  const long kidnap_at = args.count("kidnap-at") ? std::stol(args["kidnap-at"]) : -1;
  const double kidnap_distance =
      args.count("kidnap-distance") ? std::stod(args["kidnap-distance"]) : 50.0;
  bool kidnapping = false, kidnapped = false;
  Eigen::Vector3d kidnap_from = Eigen::Vector3d::Zero();
  double kidnap_stamp = 0.0, time_shift = 0.0, kidnap_jump = 0.0;
  double kidnap_detected_s = -1.0, kidnap_recovered_s = -1.0;
  size_t kidnap_skipped = 0;
  bool kidnap_recovered_correct = false;
  // Where the vehicle landed: its distance to the nearest map keyframe then, and the drive time
  // until it first came within kKidnapOnMap of one (a landing off the mapped path cannot be
  // re-localised before).
  constexpr double kKidnapOnMap = 10.0;
  double kidnap_landing_distance = -1.0, kidnap_on_map_s = -1.0;
  DriveScan scan;
  const auto t_run = Clock::now();
  for (size_t i = 0; i < n; ++i) {
    auto t0 = Clock::now();
    if (!prefetcher.next(scan)) break;
    input_ms += msSince(t0);
    if (i < start) continue;
    if (kidnap_at >= 0 && !kidnapped && !kidnapping && static_cast<long>(i) == kidnap_at) {
      if (!scan.truth) {
        std::cerr << "offline_localization: --kidnap-at needs a drive with ground truth\n";
        return 1;
      }
      kidnapping = true;
      kidnap_from = scan.truth->translation();
      kidnap_stamp = scan.stamp;
    }
    if (kidnapping) {
      kidnap_jump = scan.truth ? (scan.truth->translation() - kidnap_from).head<2>().norm() : 0.0;
      if (kidnap_jump < kidnap_distance) {
        ++kidnap_skipped;
        printProgress(i + 1, n);
        continue;
      }
      kidnapping = false;
      kidnapped = true;
      time_shift = scan.stamp - kidnap_stamp;
    }
    scan.stamp -= time_shift;
    if (!scan.cloud && !scan.filtered) {
      std::cerr << "\noffline_localization: " << scan.error << " (scan skipped)\n";
      ++skipped;
      continue;
    }
    ++scans;
    std::optional<Eigen::Isometry3d> truth;
    if (scan.truth) truth = drive_to_map * *scan.truth;
    if (!started) {
      started = true;
      if (initial == "truth") {
        if (!truth) {
          std::cerr
              << "offline_localization: --initial-pose truth: the drive has no ground truth\n";
          return 1;
        }
        // Where the vehicle is on the map: with --map-truth, past the map's own absolute error.
        localizer.setInitialPose(truth_to_map ? *truth_to_map * *truth : *truth, scan.stamp);
      } else if (!initial.empty()) {
        double x, y, yaw;
        char c;
        std::istringstream is(initial);
        is >> x >> c >> y >> c >> yaw;
        localizer.setInitialPose(mapPoseFromXyYaw(*map, x, y, yaw), scan.stamp);
      } else if (!global) {
        if (!scan.gnss || !scan.orientation) {
          std::cerr << "offline_localization: the first scan has no GNSS fix and IMU orientation; "
                       "use --initial-pose or --global\n";
          return 1;
        }
        Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
        pose.linear() = scan.orientation->toRotationMatrix();
        pose.translation() = Eigen::Vector3d(scan.gnss->x(), scan.gnss->y(), 0.0);
        pose = drive_to_map * pose;
        pose.translation().z() = mapHeightAt(*map, pose.translation());
        localizer.setInitialPose(pose, scan.stamp);
      }
    }
    t0 = Clock::now();
    const CloudPrefilterResult filtered =
        scan.filtered ? std::move(*scan.filtered) : prefilter.filter(*scan.cloud);
    prefilter_ms += scan.filtered ? scan.prepare_ms : msSince(t0);
    const size_t global_attempts_before = localizer.stats().global_attempts;
    if (use_gnss && scan.gnss)
      localizer.setGnssFix(
          scan.stamp,
          (drive_to_map * Eigen::Vector3d(scan.gnss->x(), scan.gnss->y(), 0.0)).head<2>(),
          scan.gnss_std.value_or(0.0));
    t0 = Clock::now();
    const LocalizationOutput out =
        use_imu ? localizer.process(scan.stamp, filtered.cloud, scan.angular_velocity,
                                    scan.linear_acceleration)
                : localizer.process(scan.stamp, filtered.cloud);
    localize_ms += msSince(t0);

    if (localizer.stats().global_attempts > global_attempts_before)
      logGlobalAttempt(
          global_log, scan.stamp, localizer.lastGlobal(),
          truth && truth_to_map ? std::optional<Eigen::Isometry3d>(*truth_to_map * *truth) : truth);
    double err_t = std::nan(""), err_yaw = std::nan("");
    if (truth) {
      err_t = (out.pose.translation() - truth->translation()).head<2>().norm();
      err_yaw = Eigen::AngleAxisd(truth->linear().transpose() * out.pose.linear()).angle();
    }
    const bool localized = out.status == LocalizationStatus::kTracking ||
                           out.status == LocalizationStatus::kPredicted ||
                           out.status == LocalizationStatus::kRelocalized;
    if (localized) {
      if (!localized_once) first_localized = scans;
      localized_once = true;
      estimate.push_back({scan.stamp, out.pose});
      if (truth) {
        truth_at_estimate.push_back({scan.stamp, *truth});
        all_error.add(err_t, err_yaw);
        if (out.status == LocalizationStatus::kTracking) tracking_error.add(err_t, err_yaw);
        if (truth_to_map) {
          const Eigen::Isometry3d t = *truth_to_map * *truth;
          const double e = (out.pose.translation() - t.translation()).head<2>().norm();
          const double y = Eigen::AngleAxisd(t.linear().transpose() * out.pose.linear()).angle();
          all_error_map.add(e, y);
          if (out.status == LocalizationStatus::kTracking) tracking_error_map.add(e, y);
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
          last_relocalization_correct = check_t <= 0.5 && check_yaw <= 2.0 * M_PI / 180;
          if (!last_relocalization_correct) ++wrong_relocalizations;
        }
      }
    } else if (out.status == LocalizationStatus::kOffMap) {
      off_map.push_back({scan.stamp, out.pose});
    }
    if (kidnapped) {
      if (truth && kidnap_on_map_s < 0.0) {
        const double d =
            localizer.distanceToMap((truth_to_map ? *truth_to_map * *truth : *truth).translation());
        if (kidnap_landing_distance < 0.0) kidnap_landing_distance = d;
        if (d <= kKidnapOnMap) kidnap_on_map_s = scan.stamp - kidnap_stamp;
      }
      if (out.diverged && kidnap_detected_s < 0.0) kidnap_detected_s = scan.stamp - kidnap_stamp;
      if (out.status == LocalizationStatus::kRelocalized && kidnap_detected_s >= 0.0 &&
          kidnap_recovered_s < 0.0) {
        kidnap_recovered_s = scan.stamp - kidnap_stamp;
        kidnap_recovered_correct = last_relocalization_correct;
      }
    }
    status_csv << scan.stamp << ' ' << toString(out.status) << ' ' << out.fitness << ' '
               << out.distance_to_map << ' ' << out.pose.translation().x() << ' '
               << out.pose.translation().y() << ' ' << yawOfPose(out.pose) << ' ' << err_t << ' '
               << err_yaw * 180.0 / M_PI << '\n';
    printProgress(i + 1, n);
  }
  const double wall_s = msSince(t_run) / 1000.0;

  const std::string out_dir = args["output"];
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  bool ok = writeTumTrajectory(out_dir + "/trajectory_tum.txt", estimate, &error);
  ok = ok && writeTumTrajectory(out_dir + "/ground_truth_tum.txt", truth_at_estimate, &error);
  ok = ok && writeTumTrajectory(out_dir + "/off_map_tum.txt", off_map, &error);
  ok = ok && writeFileAtomically(out_dir + "/status.csv", status_csv.str(), &error);
  ok = ok && writeFileAtomically(out_dir + "/global_attempts.csv", global_log.str(), &error);

  const LocalizationStats& s = localizer.stats();
  const double per_scan = scans ? 1.0 / scans : 0.0;
  std::ostringstream j;
  j << std::setprecision(6) << "{\"map\": \"" << args["map"] << "\", \"scans\": " << scans
    << ", \"skipped\": " << skipped << ", \"localized\": " << estimate.size()
    << ", \"tracking\": " << s.tracking << ", \"predicted\": " << s.predicted
    << ", \"off_map\": " << s.off_map << ", \"off_map_odometry\": " << s.off_map_odometry
    << ", \"not_localized\": " << s.uninitialized << ", \"relocalized\": " << s.relocalizations
    << ", \"divergences\": " << s.divergences << ", \"global_attempts\": " << s.global_attempts
    << ", \"global_failures\": " << s.global_failures
    << ", \"global_by_side_view\": " << s.global_by_side_view
    << ", \"osm_wall_buildings\": " << wall_buildings
    << ", \"global_osm_searches\": " << s.global_osm_searches
    << ", \"global_by_osm_walls\": " << s.global_by_osm_walls
    << ", \"global_osm_ms\": " << s.global_osm_ms
    << ", \"gnss_used\": " << (use_gnss ? "true" : "false")
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
    << ", \"first_localized_scan\": " << (localized_once ? long(first_localized) : -1L)
    << ", \"wrong_relocalizations\": " << wrong_relocalizations;
  if (kidnap_at >= 0)
    j << ", \"kidnap\": {\"at_scan\": " << kidnap_at << ", \"jump_m\": " << kidnap_jump
      << ", \"skipped_scans\": " << kidnap_skipped
      << ", \"landing_distance_to_map_m\": " << kidnap_landing_distance
      << ", \"within_10m_of_map_after_s\": " << kidnap_on_map_s
      << ", \"detected_after_s\": " << kidnap_detected_s
      << ", \"recovered_after_s\": " << kidnap_recovered_s
      << ", \"recovered_correct\": " << (kidnap_recovered_correct ? "true" : "false") << "}";
  j << ", \"error_tracking\": " << tracking_error.json() << ", \"error_all\": " << all_error.json()
    << ", \"error_tracking_vs_map\": " << tracking_error_map.json()
    << ", \"error_all_vs_map\": " << all_error_map.json() << ", \"timing\": {\"wall_s\": " << wall_s
    << ", \"scans_per_s\": " << (wall_s > 0 ? scans / wall_s : 0.0)
    << ", \"real_time_factor\": " << (wall_s > 0 ? scans / wall_s / 10.0 : 0.0)
    << ", \"map_load_ms\": " << load_ms << ", \"localizer_init_ms\": " << init_ms
    << ", \"input_ms_per_scan\": " << input_ms * per_scan
    << ", \"prefilter_ms_per_scan\": " << prefilter_ms * per_scan
    << ", \"prefilter_ahead\": " << (prefilter_ahead ? "true" : "false")
    << ", \"localize_ms_per_scan\": " << localize_ms * per_scan
    << ", \"registration_ms_per_scan\": " << s.registration_ms * per_scan
    << ", \"local_map_ms_per_scan\": " << s.local_map_ms * per_scan
    << ", \"local_map_builds\": " << s.local_map_builds << ", \"global_ms_total\": " << s.global_ms
    << ", \"global_ms_per_attempt\": " << (s.global_attempts ? s.global_ms / s.global_attempts : 0)
    << ", \"filter_ms_per_scan\": " << s.filter_ms * per_scan << "}}";
  std::ostringstream table;
  table << std::fixed << std::setprecision(2) << "offline_localization: " << scans << " scans in "
        << wall_s << " s (" << (wall_s > 0 ? scans / wall_s : 0.0) << " scans/s, x"
        << (wall_s > 0 ? scans / wall_s / 10.0 : 0.0) << " real time)\n"
        << "  localized " << estimate.size() << " (tracking " << s.tracking << ", predicted "
        << s.predicted << ", re-localized " << s.relocalizations << "), off map " << s.off_map
        << " (" << s.off_map_odometry << " carried by scan-to-scan registration)"
        << ", not localized " << s.uninitialized << ", divergences " << s.divergences << "\n"
        << "  per scan [ms]: input " << input_ms * per_scan << ", prefilter "
        << (prefilter_ahead ? "(ahead, on the reading thread) " : "") << prefilter_ms * per_scan
        << ", localize " << localize_ms * per_scan << " (registration "
        << s.registration_ms * per_scan << ", local map " << s.local_map_ms * per_scan << " over "
        << s.local_map_builds << " builds, filter " << s.filter_ms * per_scan << ")\n"
        << "  global localisation: " << s.global_attempts << " attempts, " << s.global_failures
        << " failed, " << (s.global_attempts ? s.global_ms / s.global_attempts : 0.0)
        << " ms each; Scan Context limit " << s.global_descriptor_limit << " (from "
        << s.global_impostor_pairs << " pairs of different places); overlap limit "
        << s.global_overlap_limit << " (own places " << s.global_overlap_own_low << " over "
        << s.global_overlap_own << ", impostors " << s.global_overlap_impostor_high << " over "
        << s.global_overlap_impostors << ", learnt in " << s.global_overlap_learn_ms << " ms)\n"
        << "  map: " << map->keyframes.size() << " keyframes, " << map->map_cloud->size()
        << " points (loaded in " << load_ms << " ms, localizer ready in " << init_ms << " ms)\n";
  if (kidnap_at >= 0)
    table << std::setprecision(2) << "  kidnap at scan " << kidnap_at << " (" << kidnap_jump
          << " m, " << kidnap_skipped << " scans skipped, landed " << kidnap_landing_distance
          << " m from the map, within " << kKidnapOnMap << " m of it after " << kidnap_on_map_s
          << " s): detected after " << kidnap_detected_s << " s, re-localised after "
          << kidnap_recovered_s << " s of drive ("
          << (kidnap_recovered_correct ? "correct" : "WRONG or none") << ")\n";
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
  ok = ok && writeFileAtomically(out_dir + "/timing.json", j.str() + "\n", &error);
  ok = ok && writeFileAtomically(out_dir + "/timing.txt", table.str(), &error);
  if (!ok) {
    std::cerr << "offline_localization: " << error << "\n";
    return 1;
  }
  if (json)
    std::cout << j.str() << "\n";
  else
    std::cout << table.str();
  return 0;
}
