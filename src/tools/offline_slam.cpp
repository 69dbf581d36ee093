// offline_slam: the SLAM pipeline on a KITTI raw drive folder, without a ROS master, as fast as
// the CPU allows. Writes what save_map writes, the odometry-only keyframe trajectory, the OXTS
// ground truth of the keyframes (KITTI raw's GPS/INS, the simulator's true poses) and a timing
// report.
//
//   offline_slam --kitti-raw DRIVE_DIR --output DIR [--calib-dir DIR] [--osm FILE.osm|.pbf]
//                [--config OVERRIDES.yaml (default config/kitti.yaml)] [--no-osm] [--no-loops]
//                [--max-scans N] [--json]
//                [--initial-heading imu|global_matching] [--no-imu] [--dump DIR]
// With OXTS data the IMU's roll/pitch become attitude priors (unless --no-imu).
#include <filesystem>
#include <iostream>
#include <map>
#include <string>

#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
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
  std::cerr << "offline_slam: " << why << "\n"
            << "usage: offline_slam --kitti-raw DRIVE_DIR --output DIR [--calib-dir DIR]\n"
               "       [--osm FILE] [--config OVERRIDES.yaml] [--no-osm] [--no-loops]\n"
               "       [--max-scans N] [--initial-heading imu|global_matching] [--no-imu]\n"
               "       [--dump DIR] [--json]\n";
  return 2;
}

Eigen::Isometry3d oxtsPose(const OxtsRecord& r, const EnuConverter& enu) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = (Eigen::AngleAxisd(r.yaw, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(r.pitch, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(r.roll, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation() = enu.toEnu(r.lat, r.lon, r.alt);
  return pose;
}

void progress(size_t done, size_t total) {
  if (total == 0 || (done % 10 != 0 && done != total)) return;
  const int width = 40;
  const int filled = static_cast<int>(width * done / total);
  std::cerr << "\r[" << std::string(filled, '#') << std::string(width - filled, ' ') << "] " << done
            << "/" << total << (done == total ? "\n" : "") << std::flush;
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> args;
  bool json = false, use_osm = true, use_loops = true, use_imu = true;
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
    } else if (a.rfind("--", 0) == 0 && i + 1 < argc) {
      args[a.substr(2)] = argv[++i];
    } else {
      return usage("unexpected argument '" + a + "'");
    }
  }
  if (!args.count("kitti-raw") || !args.count("output"))
    return usage("--kitti-raw and --output are required");

  SlamPipelineParams params;
  std::string error;
  // KITTI raw layout (real or simulated): base_link is the OXTS unit, as in launch/kitti.launch.
  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  if (!loadPipelineParams(config_dir,
                          args.count("config") ? args["config"] : config_dir + "/kitti.yaml",
                          params, &error)) {
    std::cerr << "offline_slam: " << error << "\n";
    return 1;
  }
  params.use_loops = params.use_loops && use_loops;
  params.backend.use_osm = params.backend.use_osm && use_osm;

  KittiRawDrive drive;
  if (!openKittiRawDrive(args["kitti-raw"], args.count("calib-dir") ? args["calib-dir"] : "", drive,
                         &error)) {
    std::cerr << "offline_slam: " << error << "\n";
    return 1;
  }
  // base_link is the OXTS/IMU frame (as kitti2bag's tf_static): p_base = inv(T_velo_imu) p_velo.
  params.prefilter.sensor_to_base = drive.T_velo_imu.inverse();

  std::shared_ptr<OsmMapSource> source;
  if (params.backend.use_osm) {
    if (!args.count("osm")) return usage("--osm FILE is required unless --no-osm");
    auto file = std::make_shared<FileMapSource>(args["osm"]);
    if (!file->loaded()) {
      std::cerr << "offline_slam: " << file->loadError() << "\n";
      return 1;
    }
    source = file;
  }
  OxtsRecord first;
  if (drive.oxts_files.empty() || !readOxtsFile(drive.oxts_files.front(), first, &error)) {
    std::cerr << "offline_slam: no usable first GPS fix: " << error << "\n";
    return 1;
  }
  // The initial heading from the IMU of the first OXTS record (the thesis' initial_orient),
  // unless global matching with unbounded rotation is asked for.
  const std::string heading = args.count("initial-heading") ? args["initial-heading"] : "imu";
  if (heading == "imu") {
    params.backend.initial_yaw_known = true;
    params.backend.initial_yaw = first.yaw;
  } else if (heading != "global_matching") {
    return usage("--initial-heading takes imu or global_matching");
  }
  SlamPipeline pipeline(params, source);

  pipeline.setOrigin(first.lat, first.lon, first.alt);
  const EnuConverter enu(first.lat, first.lon, first.alt);

  size_t n = drive.scan_files.size();
  if (args.count("max-scans")) n = std::min<size_t>(n, std::stoul(args["max-scans"]));
  std::map<double, Eigen::Isometry3d> truth_by_stamp;
  for (size_t i = 0; i < n; ++i) {
    auto cloud = std::make_shared<PointCloud>();
    if (!readKittiBin(drive.scan_files[i], *cloud, &error)) {
      std::cerr << "\noffline_slam: " << error << " (scan skipped)\n";
      continue;
    }
    const double stamp = static_cast<double>(drive.scan_stamps[i]) * 1e-9;
    OxtsRecord r;
    std::optional<Eigen::Vector2d> attitude;
    if (i < drive.oxts_files.size() && readOxtsFile(drive.oxts_files[i], r)) {
      truth_by_stamp[stamp] = oxtsPose(r, enu);
      if (use_imu) attitude = Eigen::Vector2d(r.roll, r.pitch);
    }
    pipeline.processScan(stamp, cloud, attitude);
    progress(i + 1, n);
  }
  const BackendUpdateReport report = pipeline.finish();

  const std::string out = args["output"];
  const MapExportResult saved = saveMap(pipeline.backend(), out, 0.2);
  if (!saved.success) {
    std::cerr << "offline_slam: " << saved.message << "\n";
    return 1;
  }
  if (args.count("dump")) {
    const MapExportResult dumped = dumpGraph(pipeline.backend(), args["dump"]);
    if (!dumped.success) std::cerr << "offline_slam: dump failed: " << dumped.message << "\n";
  }
  Trajectory truth;
  for (const auto& sp : pipeline.backend().trajectory()) {
    auto it = truth_by_stamp.find(sp.stamp);
    if (it != truth_by_stamp.end()) truth.push_back({sp.stamp, it->second});
  }
  writeTumTrajectory(out + "/ground_truth_tum.txt", truth);
  writeTumTrajectory(out + "/odometry_tum.txt", pipeline.backend().odomTrajectory());
  writeFileAtomically(out + "/timing.json", pipeline.timingJson() + "\n");
  writeFileAtomically(out + "/timing.txt", pipeline.timingTable());

  if (json) {
    std::cout << pipeline.timingJson() << "\n";
  } else {
    std::cout << pipeline.timingTable() << "final optimisation: chi2 " << report.phase1.final_chi2
              << ", " << report.overlap_edges << " overlap edges\n"
              << saved.message << " in " << out << "\n";
  }
  return 0;
}
