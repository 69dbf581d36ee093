// offline_slam: the SLAM pipeline on a KITTI raw drive folder or a bag (as kitti2bag writes it),
// without a ROS master, as fast as the CPU allows. Writes what save_map writes, the
// odometry-only keyframe trajectory, the ground truth of the keyframes (KITTI raw's GPS/INS, the
// simulator's true poses; the bag's ground_truth topic), a timing report and the map package
// for offline_localization (OUT/map_package, doc/localization.md).
//
//   offline_slam (--kitti-raw DRIVE_DIR [--calib-dir DIR] | --bag FILE.bag
//                 | --scans DIR (--origin-oxts FILE | --origin LAT,LON,ALT[,YAW_DEG])
//                   [--rate HZ] [--calib FILE]) --output DIR
//                [--osm FILE.osm|.pbf | --overpass URL] [--no-osm] [--no-loops]
//                [--config OVERRIDES.yaml (default config/kitti.yaml; simulated drives: sim.yaml)]
//                [--max-scans N] [--json]
//                [--initial-heading imu|global_matching] [--no-imu] [--dump DIR]
//                [--dump-without-clouds]
//                [--cloud-topic velodyne_points] [--gps-topic gps/fix] [--imu-topic imu/data]
//                [--ground-truth-topic ground_truth] [--base-frame base_link]
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
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "osm_graph_slam/common/memory_tuning.h"
#include "osm_graph_slam/drive_io/drive_source.h"
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

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

int usage(const std::string& why) {
  std::cerr
      << "offline_slam: " << why << "\n"
      << "usage: offline_slam (--kitti-raw DRIVE_DIR [--calib-dir DIR] | --bag FILE.bag\n"
         "       | --scans DIR (--origin-oxts FILE | --origin LAT,LON,ALT[,YAW_DEG])\n"
         "         [--rate HZ] [--calib FILE])\n"
         "       --output DIR [--osm FILE | --overpass URL] [--config OVERRIDES.yaml]\n"
         "       [--no-osm] [--no-loops] [--max-scans N]\n"
         "       [--initial-heading imu|global_matching] [--no-imu] [--dump DIR] [--json]\n"
         "       [--dump-without-clouds]   (the dump without keyframes/*.pcd: replay_backend\n"
         "                                  does not read them)\n"
         "       [--cloud-topic T] [--gps-topic T] [--imu-topic T]\n"
         "       [--ground-truth-topic T] [--base-frame F]   (bag topics and frame)\n";
  return 2;
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

}  // namespace

int main(int argc, char** argv) {
  reuseFreedMemory();  // scan-sized buffers stay in the heap (common/memory_tuning.h)
  std::map<std::string, std::string> args;
  bool json = false, use_osm = true, use_loops = true, use_imu = true, dump_clouds = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--json") {
      json = true;
    } else if (a == "--no-osm") {
      use_osm = false;
    } else if (a == "--no-loops") {
      use_loops = false;
    } else if (a == "--no-imu") {
      use_imu = false;
    } else if (a == "--dump-without-clouds") {
      dump_clouds = false;
    } else if (a.rfind("--", 0) == 0 && i + 1 < argc) {
      args[a.substr(2)] = argv[++i];
    } else {
      return usage("unexpected argument '" + a + "'");
    }
  }
  if (args.count("kitti-raw") + args.count("bag") + args.count("scans") != 1)
    return usage("exactly one of --kitti-raw, --bag and --scans is required");
  if (!args.count("output")) return usage("--output is required");
  if (args.count("osm") && args.count("overpass"))
    return usage("--osm and --overpass exclude each other");

  SlamPipelineParams params;
  std::string error;
  // KITTI raw layout (real or simulated): base_link is the OXTS unit, as in launch/kitti.launch.
  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  if (!loadPipelineParams(config_dir, argOr(args, "config", config_dir + "/kitti.yaml"), params,
                          &error)) {
    std::cerr << "offline_slam: " << error << "\n";
    return 1;
  }
  params.use_loops = params.use_loops && use_loops;
  params.backend.use_osm = params.backend.use_osm && use_osm;

  if (args.count("kitti-raw")) {
    // simulate_urban writes sim_info.json two levels above the drive folder.
    std::filesystem::path drive_dir = std::filesystem::absolute(args["kitti-raw"]);
    if (drive_dir.filename().empty()) drive_dir = drive_dir.parent_path();  // "DRIVE/"
    if (!args.count("config") &&
        std::filesystem::exists(drive_dir.parent_path().parent_path() / "sim_info.json"))
      std::cerr << "offline_slam: note: " << drive_dir.string()
                << " was written by simulate_urban, whose prior misplaces every building on its "
                   "own; its overrides are --config config/sim.yaml (using config/kitti.yaml)\n";
  }
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
  // The initial heading from the first IMU orientation (the thesis' initial_orient), unless
  // global matching with unbounded rotation is asked for.
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
  SlamPipeline pipeline(params, source);
  pipeline.setOrigin(drive->lat, drive->lon, drive->alt);

  size_t n = drive->size();
  if (args.count("max-scans")) n = std::min<size_t>(n, std::stoul(args["max-scans"]));
  std::map<double, Eigen::Isometry3d> truth_by_stamp;
  DriveScan scan;
  // The prefilter runs on the reading thread, so that it overlaps the tracking of the scans
  // before it (on 2 cores the tracker's threads leave a core partly idle).
  const CloudPrefilter& prefilter = pipeline.prefilter();
  pipeline.startClock();
  ScanPrefetcher prefetcher(*drive, n, 8, [&prefilter](DriveScan& s) {
    s.filtered = prefilter.filter(*s.cloud);
    s.cloud.reset();  // the raw scan is not needed any more
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
    pipeline.processFiltered(scan.stamp, *scan.filtered, scan.prepare_ms, aiding);
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

  const TrackingStats tracking = pipeline.timings().tracking;
  if (tracking.lost_events > 0)
    std::cerr << "offline_slam: WARNING: the track was lost " << tracking.lost_events
              << " time(s): " << tracking.scans_while_lost << " of " << tracking.scans
              << " scans came while no keyframe was made (longest "
              << tracking.longest_no_keyframe_s << " s); see timing.txt\n";
  if (json) {
    std::cout << pipeline.timingJson() << "\n";
  } else {
    std::cout << pipeline.timingTable() << "final optimisation: chi2 " << report.phase1.final_chi2
              << ", " << report.overlap_edges << " overlap edges\n"
              << saved.message << " in " << out << "\n";
  }
  return 0;
}
