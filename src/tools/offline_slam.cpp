// offline_slam: the SLAM pipeline on a KITTI raw drive folder or a bag (as kitti2bag writes it),
// without a ROS master, as fast as the CPU allows. Writes what save_map writes, the
// odometry-only keyframe trajectory, the ground truth of the keyframes (KITTI raw's GPS/INS, the
// simulator's true poses; the bag's ground_truth topic), a timing report, the map package
// for offline_localization (OUT/map_package, doc/localization.md) and, with a prior, the prior
// buildings it used (buildings_prior.geojson). The options: offline_slam --help.
//
// The first GPS fix is the map origin; the first IMU orientation (OXTS record) the initial
// heading, and the IMU's roll/pitch at each keyframe an attitude prior (unless --no-imu).
// --scans: a folder of KITTI .bin scans with one georeference for the first scan (a drive
// without per-scan OXTS, e.g. kitti_raw_0005): stamps at --rate (10 Hz), no IMU; without a yaw
// the heading comes from global matching (--initial-heading global_matching). --calib: the
// LiDAR mounting (calib_imu_to_velo.txt, or a tracking-layout file with Tr_imu_to_velo), so that
// base_link is the IMU frame as in KITTI raw; without it base_link is the LiDAR frame.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>

#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/drive_io/drive_source.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/io/loop_closure_file.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_map_source.h"
#include "osm_graph_slam/slam/map_export.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "osm_graph_slam/slam/slam_pipeline.h"
#include "support/command_line.h"
#include "support/drive_options.h"
#include "support/gnss_option.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::addDriveSourceOptions;
using osm_graph_slam::tools::addGnssUseOption;
using osm_graph_slam::tools::CommandLine;
using osm_graph_slam::tools::GnssUse;
namespace fs = std::filesystem;

namespace {

/// What the command line switches off or asks for; the drive and the other values stay text
/// (CommandLine::values()), as openDriveSource() reads them.
struct Switches {
  bool json = false, use_osm = true, use_loops = true, use_imu = true, dump_clouds = true;
  bool handover = false;
  size_t max_scans = std::numeric_limits<size_t>::max();
  GnssUse gnss;
};

void declareOptions(CommandLine& cli, Switches& sw) {
  addDriveSourceOptions(cli);
  cli.option("--output", "DIR", "where the map, trajectories and reports are written")
      .required()
      .option("--osm", "FILE", "the OSM prior (.osm or .pbf)")
      .option("--overpass", "URL", "an Overpass endpoint to ask for the prior instead of --osm")
      .option("--config", "OVERRIDES.yaml",
              "parameter overrides (config/sim.yaml for simulated drives)")
      .defaultText("config/kitti.yaml")
      .flag("--no-osm", "no OSM prior: odometry, loops, GNSS and IMU only", &sw.use_osm, false)
      .flag("--no-loops", "no loop closures", &sw.use_loops, false);
  addGnssUseOption(cli, sw.gnss);
  cli.flag("--no-imu", "no IMU attitude priors and no IMU orientation for the tracker", &sw.use_imu,
           false)
      .option("--max-scans", "N", "read at most N scans", &sw.max_scans)
      .defaultText("all")
      .option("--initial-heading", "imu|global_matching",
              "the first keyframe's heading: the first IMU orientation, or global matching "
              "against the prior with unbounded rotation")
      .defaultText("imu")
      .option("--resume", "DIR",
              "continue the map an earlier run saved in DIR (its --output): this drive becomes a "
              "new session of it, placed by the global localiser or its GNSS fixes")
      .flag("--handover",
            "with --resume: localise on the saved map first and map only once the drive has "
            "left it (drive_tum.txt: the localiser's poses, then the new session's)",
            &sw.handover)
      .option("--dump", "DIR", "also dump the graph for replay_backend")
      .flag("--dump-without-clouds",
            "the dump without keyframes/*.pcd (replay_backend does not read them)", &sw.dump_clouds,
            false)
      .flag("--json", "print the timing report as JSON", &sw.json)
      .note(
          "Exactly one of --kitti-raw, --bag and --scans names the drive; --osm or --overpass "
          "is required unless --no-osm. The first GPS fix is the map origin; the first IMU "
          "orientation the initial heading. Writes what save_map writes plus "
          "buildings_prior.geojson (the OSM prior used), the odometry-only trajectory, the "
          "ground truth of the keyframes and of every scan, loops.txt and timing.json/.txt.");
}

std::string argOr(const std::map<std::string, std::string>& args, const std::string& key,
                  const std::string& fallback) {
  const auto it = args.find(key);
  return it == args.end() ? fallback : it->second;
}

/// The accepted loop closures with their keyframes named by stamp.
std::vector<StampedLoopClosure> stampedLoops(const GraphBackend& backend) {
  std::map<uint64_t, double> stamps;
  for (const auto& kf : backend.keyframes()) stamps[kf.id] = kf.stamp;
  std::vector<StampedLoopClosure> out;
  for (const auto& loop : backend.loopClosures()) {
    const auto from = stamps.find(loop.from_id), to = stamps.find(loop.to_id);
    if (from == stamps.end() || to == stamps.end()) continue;
    out.push_back({from->second, to->second, loop.relative_pose});
  }
  return out;
}

/// The prior buildings the back-end used, in the format of buildings_corrected.geojson, so that
/// a plot of the output folder shows both (scripts/plot_map_overlay.py).
void writePriorBuildings(const GraphBackend& backend, const std::string& out) {
  std::vector<Building> priors;
  for (const auto& b : backend.buildings()) priors.push_back(b.prior);
  std::string error;
  if (!writeBuildingsGeoJson(out + "/buildings_prior.geojson", priors, &error))
    std::cerr << "offline_slam: buildings_prior.geojson: " << error << "\n";
}

/// What offline_slam writes next to save_map's files: the ground truth, loops, the odometry-only
/// trajectory, the timing report and (with a prior) the prior buildings.
void writeRunFiles(const SlamPipeline& pipeline, const std::string& out,
                   const std::map<double, Eigen::Isometry3d>& truth_by_stamp) {
  Trajectory truth, truth_all_scans;
  for (const auto& sp : pipeline.backend().trajectory()) {
    auto it = truth_by_stamp.find(sp.stamp);
    if (it != truth_by_stamp.end()) truth.push_back({sp.stamp, it->second});
  }
  for (const auto& [stamp, pose] : truth_by_stamp) truth_all_scans.push_back({stamp, pose});
  writeTumTrajectory(out + "/ground_truth_tum.txt", truth);
  // The truth of every scan read: evaluate_slam's coverage sees a drive the keyframes stop short
  // of.
  writeTumTrajectory(out + "/ground_truth_scans_tum.txt", truth_all_scans);
  writeLoopClosures(out + "/loops.txt", stampedLoops(pipeline.backend()));
  writeTumTrajectory(out + "/odometry_tum.txt", pipeline.backend().odomTrajectory());
  writeFileAtomically(out + "/timing.json", pipeline.timingJson() + "\n");
  writeFileAtomically(out + "/timing.txt", pipeline.timingTable());

  if (pipeline.backend().params().use_osm) writePriorBuildings(pipeline.backend(), out);
}

void warnIfTrackLost(const TrackingStats& tracking) {
  if (tracking.lost_events > 0)
    std::cerr << "offline_slam: WARNING: the track was lost " << tracking.lost_events
              << " time(s): " << tracking.scans_while_lost << " of " << tracking.scans
              << " scans came while no keyframe was made (longest "
              << tracking.longest_no_keyframe_s << " s); see timing.txt\n";
}

/// A simulated drive run with the real-data overrides is worth a note: simulate_urban writes
/// sim_info.json two levels above the drive folder.
void noteSimulatedDrive(const std::map<std::string, std::string>& args) {
  if (!args.count("kitti-raw") || args.count("config")) return;
  std::filesystem::path drive_dir = std::filesystem::absolute(args.at("kitti-raw"));
  if (drive_dir.filename().empty()) drive_dir = drive_dir.parent_path();  // "DRIVE/"
  if (std::filesystem::exists(drive_dir.parent_path().parent_path() / "sim_info.json"))
    std::cerr << "offline_slam: note: " << drive_dir.string()
              << " was written by simulate_urban, whose prior misplaces every building on its "
                 "own; its overrides are --config config/sim.yaml (using config/kitti.yaml)\n";
}

/// A fix of the drive's own ENU frame in the map's (they differ when resuming on a saved map).
void moveFixToMap(const EnuConverter& drive, const EnuConverter& map, ScanAiding& aiding) {
  if (drive.originLat() == map.originLat() && drive.originLon() == map.originLon() &&
      drive.originAlt() == map.originAlt())
    return;
  const Eigen::Vector3d geo = drive.toGeodetic(Eigen::Vector3d(
      aiding.gnss_position->x(), aiding.gnss_position->y(), aiding.gnss_altitude.value_or(0.0)));
  const Eigen::Vector3d enu = map.toEnu(geo.x(), geo.y(), geo.z());
  aiding.gnss_position = enu.head<2>();
  if (aiding.gnss_altitude) aiding.gnss_altitude = enu.z();
}

std::string resumeJson(const MapResumeStatus& s) {
  std::ostringstream o;
  o << std::setprecision(10) << "{\"session\": " << s.session
    << ", \"saved_keyframes\": " << s.saved_keyframes
    << ", \"placed\": " << (s.placed ? "true" : "false")
    << ", \"placed_by_gnss\": " << (s.placed_by_gnss ? "true" : "false")
    << ", \"placed_by_localizer\": " << (s.placed_by_localizer ? "true" : "false")
    << ", \"localizer_ties\": " << s.localizer_ties
    << ", \"localizer_ties_refused\": " << s.localizer_ties_refused
    << ", \"placed_at\": " << (s.placed_at ? std::to_string(*s.placed_at) : "null")
    << ", \"placement\": [" << s.placement.translation().x() << ", "
    << s.placement.translation().y() << ", " << s.placement.translation().z() << ", "
    << planarPose(s.placement).theta << "], \"global_attempts\": " << s.global_attempts
    << ", \"global_answers\": " << s.global_answers
    << ", \"answers_disagreeing\": " << s.answers_disagreeing
    << ", \"placements_unconfirmed\": " << s.placements_unconfirmed
    << ", \"inter_session_loops\": " << s.inter_session_loops
    << ", \"loops_inconsistent\": " << s.loops_inconsistent << ", \"replay_ms\": " << s.replay_ms
    << ", \"global_ms\": " << s.global_ms << ", \"loops_ms\": " << s.loops_ms << "}";
  return o.str();
}

}  // namespace

int main(int argc, char** argv) {
  reuseFreedMemory();  // scan-sized buffers stay in the heap (common/memory_tuning.h)
  Switches sw;
  CommandLine cli("offline_slam",
                  "The SLAM pipeline on a KITTI raw drive folder, a bag or a folder of scans, "
                  "without a ROS master, as fast as the CPU allows.");
  declareOptions(cli, sw);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::map<std::string, std::string> args = cli.values();
  const auto usage = [&cli](const std::string& why) { return cli.fail(why); };
  const bool json = sw.json, use_osm = sw.use_osm, use_loops = sw.use_loops;
  const bool use_imu = sw.use_imu, dump_clouds = sw.dump_clouds;
  if (args.count("kitti-raw") + args.count("bag") + args.count("scans") != 1)
    return usage("exactly one of --kitti-raw, --bag and --scans is required");
  if (args.count("osm") && args.count("overpass"))
    return usage("--osm and --overpass exclude each other");

  SlamPipelineParams params;
  std::string error;
  // KITTI raw layout (real or simulated): base_link is the OXTS unit, as in launch/kitti.launch.
  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  const std::string overrides = argOr(args, "config", config_dir + "/kitti.yaml");
  if (!loadPipelineParams(config_dir, overrides, params, &error)) {
    std::cerr << "offline_slam: " << error << "\n";
    return 1;
  }
  params.use_loops = params.use_loops && use_loops;
  params.backend.use_osm = params.backend.use_osm && use_osm;
  sw.gnss.apply(params.backend.gnss);

  noteSimulatedDrive(args);
  const std::unique_ptr<DriveSource> drive =
      openDriveSource(args, "offline_slam", &error, params.backend.inputs);
  if (!drive) {
    std::cerr << "offline_slam: " << error << "\n";
    return 1;
  }
  params.prefilter.sensor_to_base = drive->sensor_to_base;

  std::shared_ptr<OsmMapSource> source;
  if (params.backend.use_osm) {
    if (args.count("overpass")) {
      OverpassParams overpass;
      overpass.endpoint = args["overpass"];
      source = std::make_shared<OverpassMapSource>(overpass);
    } else if (args.count("osm")) {
      auto file = std::make_shared<FileMapSource>(args["osm"]);
      if (!file->loaded()) {
        std::cerr << "offline_slam: " << file->loadError() << "\n";
        return 1;
      }
      source = file;
    } else {
      return usage("--osm FILE or --overpass URL is required unless --no-osm");
    }
  }
  // The drive's own start heading (its first OXTS record, the bag's IMU at its first cloud, a
  // scan folder's georeference; the thesis' initial_orient) is the known heading that
  // KeyframeAiding gives the first keyframe; --initial-heading global_matching leaves it unknown
  // and the first global matching with unbounded rotation decides it.
  const std::string heading = argOr(args, "initial-heading", "imu");
  if (heading == "imu") {
    if (!drive->initial_yaw) {
      std::cerr << "offline_slam: no IMU orientation for the initial heading; use "
                   "--initial-heading global_matching\n";
      return 1;
    }
    params.backend.initial_yaw_known = true;
    params.backend.initial_yaw = *drive->initial_yaw;
  } else if (heading != "global_matching") {
    return usage("--initial-heading takes imu or global_matching");
  }
  if (sw.handover && !args.count("resume")) return usage("--handover needs --resume DIR");
  SlamPipeline pipeline(params, source);
  LocalizationParams localization;  // the resumed map's localiser, as the nodelet has it
  if (args.count("resume") &&
      !(loadLocalizationParams(config_dir, overrides, localization, &error) &&
        (sw.handover
             ? pipeline.handOverOn(args["resume"], MapResumeParams(), localization,
                                   LocalizationHandoverParams(), &error)
             : pipeline.resumeOn(args["resume"], MapResumeParams(), localization, &error)))) {
    std::cerr << "offline_slam: " << error << "\n";
    return 1;
  }
  pipeline.setOrigin(drive->lat, drive->lon, drive->alt);  // a resumed map keeps its own
  const EnuConverter drive_origin(drive->lat, drive->lon, drive->alt);
  const EnuConverter map_origin = pipeline.backend().origin().value_or(drive_origin);

  const size_t n = std::min(drive->size(), sw.max_scans);
  std::map<double, Eigen::Isometry3d> truth_by_stamp;
  DriveScan scan;
  // The prefilter runs on the reading thread, so that it overlaps the tracking of the scans
  // before it (on 2 cores the tracker's threads leave a core partly idle).
  const CloudPrefilter& prefilter = pipeline.prefilter();
  pipeline.startClock();
  const bool keep_raw = pipeline.usesSensorCloud();  // the multi-cue tracker projects it
  ScanPrefetcher prefetcher(*drive, n, 8, [&prefilter, keep_raw](DriveScan& s) {
    s.filtered = prefilter.filter(*s.cloud);
    if (!keep_raw) s.cloud.reset();  // the raw scan is not needed any more
  });
  auto readScan = [&] {
    const auto t0 = std::chrono::steady_clock::now();
    const bool ok = prefetcher.next(scan);
    pipeline.addInputTime(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    return ok;
  };
  for (size_t i = 0; i < n && readScan(); ++i) {
    if (!scan.filtered) {
      std::cerr << "\noffline_slam: " << scan.error << " (scan skipped)\n";
      continue;
    }
    if (scan.truth) truth_by_stamp[scan.stamp] = *scan.truth;
    ScanAiding aiding;
    if (use_imu && params.backend.inputs.use_imu) aiding.gravity_roll_pitch = scan.roll_pitch;
    if (use_imu) aiding.imu_orientation = scan.orientation;
    aiding.gnss_position = scan.gnss;
    aiding.gnss_std = scan.gnss_std;
    aiding.gnss_altitude = scan.gnss_altitude;
    if (scan.gnss) moveFixToMap(drive_origin, map_origin, aiding);
    pipeline.processFiltered(scan.stamp, *scan.filtered, scan.prepare_ms, aiding, scan.cloud);
    printProgress(i + 1, n);
  }
  const BackendUpdateReport report = pipeline.finish();

  const std::string out = args["output"];
  const MapExportResult saved = saveMap(pipeline.backend(), out, 0.2, &params.loop.scan_context);
  if (!saved.success) {
    std::cerr << "offline_slam: " << saved.message << "\n";
    return 1;
  }
  if (args.count("dump")) {
    const MapExportResult dumped = dumpGraph(pipeline.backend(), args["dump"], dump_clouds);
    if (!dumped.success) std::cerr << "offline_slam: dump failed: " << dumped.message << "\n";
  }
  writeRunFiles(pipeline, out, truth_by_stamp);
  if (const MapResume* resume = pipeline.resume()) {
    std::cout << "resumed: " << resume->status().text() << "\n";
    writeFileAtomically(out + "/resume.json", resumeJson(resume->status()) + "\n");
  }
  if (const LocalizationHandover* handover = pipeline.handover()) {
    writeTumTrajectory(out + "/drive_tum.txt", pipeline.drivePoses());
    if (handover->mapping())
      std::cout << "handed over to mapping at " << std::fixed << std::setprecision(3)
                << *handover->handoverStamp() << " s (" << handover->keyframesLocalized()
                << " keyframes localised before)\n";
    else
      std::cout << "never left the saved map: localised throughout, nothing mapped\n";
  }
  warnIfTrackLost(pipeline.timings().tracking);
  if (!json) std::cout << "saved: " << saved.message << "\n";  // files, and the grid's cost
  if (json) {
    std::cout << pipeline.timingJson() << "\n";
  } else {
    std::cout << pipeline.timingTable() << "final optimisation: chi2 " << report.phase1.final_chi2
              << ", " << report.overlap_edges << " overlap edges\n"
              << saved.message << " in " << out << "\n";
  }
  return 0;
}
