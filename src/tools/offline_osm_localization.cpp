// Localisation from OpenStreetMap alone, offline (a fleet vehicle in a new city, no prior drive):
// LiDAR odometry + GNSS + the scan's walls aligned with the OSM buildings.
// The options: offline_osm_localization --help.
// Runs two filters on the same odometry in one pass: with the OSM walls (the product) and
// without them (odometry + GNSS), and reports both next to the raw GNSS fixes, so a drive with
// ground truth shows what the walls add. Writes trajectory_tum.txt (with OSM), gnss_filter_tum.txt
// (without), gnss_fixes_tum.txt, ground_truth_tum.txt (when the drive has it), status.csv and
// timing.json / timing.txt.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/drive_io/drive_source.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/localization/osm_localizer.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_map_source.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "osm_graph_slam/slam/slam_pipeline.h"
#include "support/command_line.h"
#include "support/drive_options.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;

namespace {

using Clock = std::chrono::steady_clock;

/// Mean 2D error of an estimate against the truth at the same scans.
struct ErrorSum {
  double sum = 0.0, max = 0.0;
  size_t n = 0;
  void add(const Eigen::Vector2d& e) {
    sum += e.norm();
    max = std::max(max, e.norm());
    ++n;
  }
  double mean() const { return n ? sum / n : 0.0; }
};

std::vector<Building> loadBuildings(const std::string& path, const DriveSource& drive,
                                    std::string* error) {
  FileMapSource file(path);
  if (!file.loaded()) {
    *error = file.loadError();
    return {};
  }
  MapFetchResult fetched = file.fetch(GeoPoint{drive.lat, drive.lon}, 1e7);
  if (!fetched.ok) {
    *error = fetched.error;
    return {};
  }
  const EnuConverter enu(drive.lat, drive.lon, drive.alt);
  for (Building& b : fetched.buildings) enu.project(b);
  return fetched.buildings;
}

std::string errorLine(const char* label, const ErrorSum& e) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(3) << label << e.mean() << " m mean, " << e.max
     << " m max over " << e.n << " scans";
  return os.str();
}

/// The two filters' answers over the drive, their errors against the truth and the time spent.
struct DriveRun {
  Trajectory est, est_gnss, fixes, truth;
  ErrorSum err_osm, err_gnss_filter, err_fixes, err_osm_seen, err_fixes_seen;
  std::ostringstream status;
  double prefilter_ms = 0.0, tracking_ms = 0.0, wall_s = 0.0;
  size_t scans = 0, lost = 0;
};

/// Both filters on the same odometry, scan by scan (at most n scans of the drive).
void runFilters(DriveSource& drive, size_t n, const CloudPrefilter& prefilter,
                KeyframeTracker& tracker, OsmLocalizer& osm, OsmLocalizer& gnss_only,
                DriveRun& run) {
  Trajectory &est = run.est, &est_gnss = run.est_gnss, &fixes = run.fixes, &truth = run.truth;
  ErrorSum &err_osm = run.err_osm, &err_gnss_filter = run.err_gnss_filter,
           &err_fixes = run.err_fixes, &err_osm_seen = run.err_osm_seen,
           &err_fixes_seen = run.err_fixes_seen;
  std::ostringstream& status = run.status;
  double &prefilter_ms = run.prefilter_ms, &tracking_ms = run.tracking_ms, prev_stamp = -1e300;
  size_t &scans = run.scans, &lost = run.lost;
  ScanPrefetcher prefetcher(drive, n, 8, [&prefilter](DriveScan& s) {
    s.filtered = prefilter.filter(*s.cloud);
    s.cloud.reset();
  });
  status << "stamp,status,osm_outcome,osm_fitness,datum_x,datum_y,error_m,gnss_filter_error_m,"
            "osm_message\n";
  const auto start = Clock::now();
  DriveScan scan;
  std::optional<double> first_yaw = drive.initial_yaw;
  // A scan seen by the walls: the last accepted match is at most this many scans old.
  int since_accepted = 1 << 20;
  while (scans < n && prefetcher.next(scan)) {
    ++scans;
    if (!scan.filtered || !scan.filtered->ok || scan.stamp <= prev_stamp) continue;
    prev_stamp = scan.stamp;
    prefilter_ms += scan.prepare_ms;
    const auto t0 = Clock::now();
    const TrackResult track = tracker.track(scan.stamp, scan.filtered->cloud);
    tracking_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (!track.has_pose()) {
      ++lost;
      continue;
    }
    std::optional<double> yaw;
    if (scan.orientation)
      yaw = planarPose(Eigen::Isometry3d(*scan.orientation)).theta;
    else if (first_yaw)
      yaw = first_yaw;
    const OsmLocalizationOutput a =
        osm.process(scan.stamp, track.pose, scan.filtered->cloud, scan.gnss, scan.gnss_std, yaw);
    const OsmLocalizationOutput b =
        gnss_only.process(scan.stamp, track.pose, nullptr, scan.gnss, scan.gnss_std, yaw);
    if (a.status == OsmLocalizationStatus::kUninitialized) continue;
    est.push_back({scan.stamp, a.pose});
    est_gnss.push_back({scan.stamp, b.pose});
    since_accepted = a.osm_outcome == "accepted" ? 0 : since_accepted + 1;
    double e_osm = -1.0, e_gnss = -1.0;
    if (scan.truth) {
      truth.push_back({scan.stamp, *scan.truth});
      const Eigen::Vector2d t = scan.truth->translation().head<2>();
      e_osm = (a.pose.translation().head<2>() - t).norm();
      e_gnss = (b.pose.translation().head<2>() - t).norm();
      err_osm.add(a.pose.translation().head<2>() - t);
      err_gnss_filter.add(b.pose.translation().head<2>() - t);
      if (scan.gnss) err_fixes.add(*scan.gnss - t);
      if (since_accepted <= 20) {
        err_osm_seen.add(a.pose.translation().head<2>() - t);
        if (scan.gnss) err_fixes_seen.add(*scan.gnss - t);
      }
    }
    if (scan.gnss) {
      Eigen::Isometry3d fix = a.pose;
      fix.translation().head<2>() = *scan.gnss;
      fixes.push_back({scan.stamp, fix});
    }
    status << std::setprecision(10) << scan.stamp << "," << toString(a.status) << ","
           << a.osm_outcome << "," << std::setprecision(4) << a.osm_fitness << "," << a.datum.x()
           << "," << a.datum.y() << "," << e_osm << "," << e_gnss << ",\"" << a.osm_message
           << "\"\n";
  }
  run.wall_s = std::chrono::duration<double>(Clock::now() - start).count();
}

/// The trajectories, status.csv and the report (timing.json / timing.txt) in `out`; the report
/// also on stdout.
void writeOutputs(const DriveRun& run, const OsmLocalizationStats& st, size_t building_count,
                  const std::string& out, bool json) {
  const Trajectory &est = run.est, &est_gnss = run.est_gnss, &fixes = run.fixes, &truth = run.truth;
  const ErrorSum &err_osm = run.err_osm, &err_gnss_filter = run.err_gnss_filter,
                 &err_fixes = run.err_fixes, &err_osm_seen = run.err_osm_seen,
                 &err_fixes_seen = run.err_fixes_seen;
  const std::ostringstream& status = run.status;
  const double prefilter_ms = run.prefilter_ms, tracking_ms = run.tracking_ms, wall_s = run.wall_s;
  const size_t scans = run.scans, lost = run.lost;
  std::filesystem::create_directories(out);
  writeTumTrajectory(out + "/trajectory_tum.txt", est);
  writeTumTrajectory(out + "/gnss_filter_tum.txt", est_gnss);
  writeTumTrajectory(out + "/gnss_fixes_tum.txt", fixes);
  if (!truth.empty()) writeTumTrajectory(out + "/ground_truth_tum.txt", truth);
  writeFileAtomically(out + "/status.csv", status.str());

  std::ostringstream report;
  report << std::fixed << std::setprecision(2) << scans << " scans (" << est.size()
         << " localised, " << lost << " without odometry), " << building_count
         << " buildings in the extract, " << wall_s << " s: " << scans / std::max(wall_s, 1e-9)
         << " scans/s\n"
         << "per scan: prefilter " << prefilter_ms / std::max<size_t>(scans, 1)
         << " ms (ahead, on the reading thread), tracking "
         << tracking_ms / std::max<size_t>(scans, 1) << " ms; walls " << st.walls_ms << " ms and "
         << "matching " << st.matching_ms << " ms over " << st.osm_attempts << " attempts\n"
         << "OSM wall matches: " << st.osm_accepted << " accepted of " << st.osm_attempts
         << " (few segments " << st.osm_few_segments << ", no buildings " << st.osm_no_buildings
         << ", failed " << st.osm_failed << ", weak " << st.osm_weak << ", gated " << st.osm_gated
         << "); GNSS fixes used " << st.gnss_used << ", rejected " << st.gnss_rejected << "\n";
  if (err_osm.n) {
    report << errorLine("error with OSM:          ", err_osm) << "\n"
           << errorLine("odometry + GNSS only:    ", err_gnss_filter) << "\n"
           << errorLine("GNSS fixes alone:        ", err_fixes) << "\n"
           << errorLine("with OSM, walls matched: ", err_osm_seen) << "\n"
           << errorLine("GNSS fixes, same scans:  ", err_fixes_seen) << "\n";
  }
  std::ostringstream j;
  j << std::setprecision(6) << "{\"scans\": " << scans << ", \"localised\": " << est.size()
    << ", \"without_odometry\": " << lost << ", \"scans_per_second\": " << scans / wall_s
    << ", \"osm_attempts\": " << st.osm_attempts << ", \"osm_accepted\": " << st.osm_accepted
    << ", \"osm_gated\": " << st.osm_gated << ", \"gnss_rejected\": " << st.gnss_rejected
    << ", \"error_mean_m\": " << err_osm.mean() << ", \"error_max_m\": " << err_osm.max
    << ", \"gnss_filter_error_mean_m\": " << err_gnss_filter.mean()
    << ", \"gnss_fix_error_mean_m\": " << err_fixes.mean()
    << ", \"error_seen_mean_m\": " << err_osm_seen.mean()
    << ", \"gnss_fix_error_seen_mean_m\": " << err_fixes_seen.mean()
    << ", \"scans_seen\": " << err_osm_seen.n << "}";
  writeFileAtomically(out + "/timing.json", j.str() + "\n");
  writeFileAtomically(out + "/timing.txt", report.str());
  std::cout << (json ? j.str() + "\n" : report.str());
}

}  // namespace

int main(int argc, char** argv) {
  reuseFreedMemory();
  bool json = false;
  size_t max_scans = std::numeric_limits<size_t>::max();
  CommandLine cli("offline_osm_localization",
                  "Localisation from OpenStreetMap alone, offline: LiDAR odometry + GNSS + the "
                  "scan's walls aligned with the OSM buildings, next to the same filter without "
                  "the walls and the raw GNSS fixes.");
  tools::addDriveSourceOptions(cli);
  cli.option("--osm", "FILE", "the OSM extract (.osm or .pbf)")
      .required()
      .option("--output", "DIR", "where the trajectories, status.csv and the report go")
      .required()
      .option("--config", "OVERRIDES.yaml", "pipeline parameter overrides (odometry, walls)")
      .option("--localizer-config", "FILE", "the localiser's parameters")
      .defaultText("config/osm_localization.yaml")
      .option("--max-scans", "N", "read at most N scans", &max_scans)
      .defaultText("all")
      .flag("--json", "print the report as JSON", &json)
      .note("Exactly one of --kitti-raw, --bag and --scans names the drive.");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::map<std::string, std::string> args = cli.values();

  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  SlamPipelineParams pipeline;
  std::string error;
  if (!loadPipelineParams(config_dir, args.count("config") ? args["config"] : "", pipeline,
                          &error)) {
    std::cerr << "offline_osm_localization: " << error << "\n";
    return 1;
  }
  const std::string loc_file = args.count("localizer-config")
                                   ? args["localizer-config"]
                                   : config_dir + "/osm_localization.yaml";
  const YamlParamReader loc_yaml = YamlParamReader::fromFile(loc_file);
  if (!loc_yaml.ok()) {
    std::cerr << "offline_osm_localization: " << loc_yaml.error() << "\n";
    return 1;
  }
  OsmLocalizerParams with_osm;
  readParams(loc_yaml, with_osm);
  OsmLocalizerParams without_osm = with_osm;
  without_osm.use_osm = false;

  const std::unique_ptr<DriveSource> drive =
      openDriveSource(args, "offline_osm_localization", &error, pipeline.backend.inputs);
  if (!drive) {
    std::cerr << "offline_osm_localization: " << error << "\n";
    return 1;
  }
  pipeline.prefilter.sensor_to_base = drive->sensor_to_base;
  pipeline.tracker.sensor_to_base = drive->sensor_to_base;  // deskewing: azimuths about the LiDAR
  std::vector<Building> buildings = loadBuildings(args["osm"], *drive, &error);
  if (buildings.empty()) {
    std::cerr << "offline_osm_localization: no buildings from " << args["osm"] << ": " << error
              << "\n";
    return 1;
  }
  const size_t building_count = buildings.size();
  OsmLocalizer osm(with_osm, std::move(buildings), pipeline.wall, pipeline.segments,
                   pipeline.backend.matcher);
  OsmLocalizer gnss_only(without_osm, {}, pipeline.wall, pipeline.segments,
                         pipeline.backend.matcher);
  const CloudPrefilter prefilter(pipeline.prefilter);
  KeyframeTracker tracker(pipeline.tracker);

  const size_t n = std::min(drive->size(), max_scans);
  DriveRun run;
  runFilters(*drive, n, prefilter, tracker, osm, gnss_only, run);
  writeOutputs(run, osm.stats(), building_count, args["output"], json);
  return 0;
}
