// offline_slam: the SLAM pipeline on a KITTI raw drive folder or a bag (as kitti2bag writes it),
// without a ROS master, as fast as the CPU allows. Writes what save_map writes, the
// odometry-only keyframe trajectory, the ground truth of the keyframes (KITTI raw's GPS/INS, the
// simulator's true poses; the bag's ground_truth topic) and a timing report.
//
//   offline_slam (--kitti-raw DRIVE_DIR [--calib-dir DIR] | --bag FILE.bag
//                 | --scans DIR (--origin-oxts FILE | --origin LAT,LON,ALT[,YAW_DEG])
//                   [--rate HZ] [--calib FILE]) --output DIR
//                [--osm FILE.osm|.pbf | --overpass URL] [--no-osm] [--no-loops]
//                [--config OVERRIDES.yaml (default config/kitti.yaml; simulated drives: sim.yaml)]
//                [--max-scans N] [--json]
//                [--initial-heading imu|global_matching] [--no-imu] [--dump DIR]
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

#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/io/loop_closure_file.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_map_source.h"
#include "osm_graph_slam/ros/bag_drive_reader.h"
#include "osm_graph_slam/slam/map_export.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "osm_graph_slam/slam/slam_pipeline.h"

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

int usage(const std::string& why) {
  std::cerr << "offline_slam: " << why << "\n"
            << "usage: offline_slam (--kitti-raw DRIVE_DIR [--calib-dir DIR] | --bag FILE.bag\n"
               "       | --scans DIR (--origin-oxts FILE | --origin LAT,LON,ALT[,YAW_DEG])\n"
               "         [--rate HZ] [--calib FILE])\n"
               "       --output DIR [--osm FILE | --overpass URL] [--config OVERRIDES.yaml]\n"
               "       [--no-osm] [--no-loops] [--max-scans N]\n"
               "       [--initial-heading imu|global_matching] [--no-imu] [--dump DIR] [--json]\n"
               "       [--cloud-topic T] [--gps-topic T] [--imu-topic T]\n"
               "       [--ground-truth-topic T] [--base-frame F]   (bag topics and frame)\n";
  return 2;
}

std::string argOr(const std::map<std::string, std::string>& args, const std::string& key,
                  const std::string& fallback) {
  const auto it = args.find(key);
  return it == args.end() ? fallback : it->second;
}

/// One scan with what the GPS/INS said at its time.
struct DriveScan {
  double stamp = 0.0;
  PointCloudPtr cloud;  ///< null: unreadable (error says why), the scan is skipped
  std::string error;
  std::optional<Eigen::Vector2d> roll_pitch;      ///< base_link in ENU
  std::optional<Eigen::Quaterniond> orientation;  ///< base_link in ENU (INS / IMU), if any
  std::optional<Eigen::Isometry3d> truth;         ///< base_link in ENU at the first fix
  std::optional<Eigen::Vector2d> gnss;            ///< the GNSS fix in the same frame
};

/// A drive: origin, initial heading, sensor mounting and the scans in order.
class DriveSource {
 public:
  virtual ~DriveSource() = default;
  virtual size_t size() const = 0;
  /// The next scan; false at the end.
  virtual bool next(DriveScan& scan) = 0;

  double lat = 0, lon = 0, alt = 0;
  std::optional<double> initial_yaw;  ///< ENU yaw of base_link at the first scan
  Eigen::Isometry3d sensor_to_base = Eigen::Isometry3d::Identity();
};

Eigen::Isometry3d oxtsPose(const OxtsRecord& r, const EnuConverter& enu) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = (Eigen::AngleAxisd(r.yaw, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(r.pitch, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(r.roll, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation() = enu.toEnu(r.lat, r.lon, r.alt);
  return pose;
}

/// KITTI raw folder: velodyne_points/*.bin with the OXTS record of the same index.
class KittiRawSource : public DriveSource {
 public:
  bool open(const std::string& dir, const std::string& calib_dir, std::string* error) {
    if (!openKittiRawDrive(dir, calib_dir, drive_, error)) return false;
    OxtsRecord first, fix;
    if (drive_.oxts_files.empty() || !readOxtsFile(drive_.oxts_files.front(), first, error)) {
      if (error) *error = "no usable first GPS fix: " + *error;
      return false;
    }
    // The map origin is the first record with a GNSS fix (a simulated outage has none).
    fix = first;
    for (size_t i = 1; !fix.hasGnssFix() && i < drive_.oxts_files.size(); ++i) {
      if (!readOxtsFile(drive_.oxts_files[i], fix, error)) return false;
    }
    if (!fix.hasGnssFix()) {
      if (error) *error = "no OXTS record of '" + dir + "' has a GNSS fix";
      return false;
    }
    lat = fix.lat;
    lon = fix.lon;
    alt = fix.alt;
    initial_yaw = first.yaw;
    enu_.emplace(fix.lat, fix.lon, fix.alt);
    // base_link is the OXTS/IMU frame (as kitti2bag's tf_static): p_base = inv(T_velo_imu) p_velo.
    sensor_to_base = drive_.T_velo_imu.inverse();
    return true;
  }
  size_t size() const override { return drive_.scan_files.size(); }
  bool next(DriveScan& scan) override {
    if (index_ >= size()) return false;
    const size_t i = index_++;
    scan = DriveScan();
    scan.stamp = static_cast<double>(drive_.scan_stamps[i]) * 1e-9;
    auto cloud = std::make_shared<PointCloud>();
    if (readKittiBin(drive_.scan_files[i], *cloud, &scan.error)) scan.cloud = cloud;
    OxtsRecord r;
    if (i < drive_.oxts_files.size() && readOxtsFile(drive_.oxts_files[i], r)) {
      scan.truth = oxtsPose(r, *enu_);  // KITTI's OXTS is RTK GNSS + INS
      if (r.hasGnssFix()) scan.gnss = enu_->toEnu(r.lat, r.lon, r.alt).head<2>();
      scan.roll_pitch = Eigen::Vector2d(r.roll, r.pitch);
      scan.orientation = Eigen::Quaterniond(oxtsPose(r, *enu_).linear());
    }
    // simulate_urban's exact records: the truth in the frame of the (measured) first fix.
    if (!drive_.truth_oxts_files.empty()) {
      scan.truth.reset();
      if (i < drive_.truth_oxts_files.size() && readOxtsFile(drive_.truth_oxts_files[i], r))
        scan.truth = oxtsPose(r, *enu_);
    }
    return true;
  }

 private:
  KittiRawDrive drive_;
  std::optional<EnuConverter> enu_;
  size_t index_ = 0;
};

/// A bag as kitti2bag writes it; the IMU and ground truth nearest to each cloud's stamp.
class BagSource : public DriveSource {
 public:
  bool open(const std::string& path, const BagDriveTopics& topics, std::string* error) {
    if (!reader_.open(path, topics, error)) return false;
    const std::optional<BagFix> fix = reader_.firstFix();
    if (!fix) {
      if (error) *error = "bag '" + path + "' has no valid fix on '" + topics.gps + "'";
      return false;
    }
    lat = fix->lat;
    lon = fix->lon;
    alt = fix->alt;
    enu_.emplace(lat, lon, alt);
    if (const auto q = reader_.firstOrientation()) initial_yaw = yawOf(*q);
    // The sensor mounting from tf_static: base_link -> the first cloud's frame.
    pending_ = reader_.nextCloud();
    const std::string frame = pending_ ? pending_->frame_id : std::string();
    const auto base_T_sensor = reader_.baseToFrame(frame);
    if (!base_T_sensor) {
      if (error)
        *error = "no static transform " + topics.base_frame + " -> '" + frame + "' on '" +
                 topics.tf_static + "' in '" + path + "'";
      return false;
    }
    sensor_to_base = *base_T_sensor;
    return true;
  }
  size_t size() const override { return reader_.numClouds(); }
  bool next(DriveScan& scan) override {
    std::optional<BagCloud> c = pending_ ? std::move(pending_) : reader_.nextCloud();
    pending_.reset();
    if (!c) return false;
    scan = DriveScan();
    scan.stamp = static_cast<double>(c->stamp_ns) * 1e-9;
    scan.cloud = c->cloud;
    scan.error = c->error;
    if (const auto q = reader_.orientationAt(c->stamp_ns)) {
      scan.roll_pitch = rollPitchOf(*q);
      scan.orientation = *q;
    }
    scan.truth = reader_.groundTruthAt(c->stamp_ns);
    // The pipeline anchors its first keyframe here, whichever cloud that is.
    if (const auto f = reader_.fixAt(c->stamp_ns))
      scan.gnss = enu_->toEnu(f->lat, f->lon, f->alt).head<2>();
    return true;
  }

 private:
  BagDriveReader reader_;
  std::optional<EnuConverter> enu_;
  std::optional<BagCloud> pending_;
};

/// A folder of KITTI .bin scans with one georeference for the first scan and no IMU: stamps at
/// a fixed rate, the GNSS fix only at the first scan (the map origin), the heading if known.
class ScanFolderSource : public DriveSource {
 public:
  bool open(const std::map<std::string, std::string>& args, std::string* error) {
    const std::string dir = args.at("scans");
    files_ = listFiles(dir, ".bin");
    if (files_.empty()) return fail(error, "no .bin scans in '" + dir + "'");
    if (args.count("rate")) rate_ = std::atof(args.at("rate").c_str());
    if (!(rate_ > 0.0)) return fail(error, "--rate must be > 0");
    ScanFolderOrigin origin;
    if (!readScanFolderOrigin(argOr(args, "origin-oxts", ""), argOr(args, "origin", ""), origin,
                              error))
      return false;
    lat = origin.lat, lon = origin.lon, alt = origin.alt;
    initial_yaw = origin.yaw;
    if (origin.oxts) first_roll_pitch_ = Eigen::Vector2d(origin.oxts->roll, origin.oxts->pitch);
    if (args.count("calib")) {
      // p_velo = T_velo_imu p_imu; base_link is the IMU frame: p_base = inv(T_velo_imu) p_velo.
      Eigen::Isometry3d T_velo_imu;
      if (!readImuToVeloCalib(args.at("calib"), T_velo_imu, error)) return false;
      sensor_to_base = T_velo_imu.inverse();
    } else {
      std::cerr << "offline_slam: note: no --calib: base_link is the LiDAR frame\n";
    }
    return true;
  }
  size_t size() const override { return files_.size(); }
  bool next(DriveScan& scan) override {
    if (index_ >= files_.size()) return false;
    const size_t i = index_++;
    scan = DriveScan();
    scan.stamp = kFirstStamp + double(i) / rate_;
    auto cloud = std::make_shared<PointCloud>();
    if (readKittiBin(files_[i], *cloud, &scan.error)) scan.cloud = cloud;
    if (i == 0) {
      scan.gnss = Eigen::Vector2d::Zero();  // the georeference is the origin
      scan.roll_pitch = first_roll_pitch_;
    }
    return true;
  }

 private:
  static bool fail(std::string* error, const std::string& why) {
    if (error) *error = why;
    return false;
  }
  static constexpr double kFirstStamp = 1.0;  ///< [s] (bags refuse stamp 0)
  std::vector<std::string> files_;
  double rate_ = 10.0;
  size_t index_ = 0;
  std::optional<Eigen::Vector2d> first_roll_pitch_;
};

/// Reads the scans on its own thread, a few ahead of the pipeline. On a cold disk reading a
/// 2 MB HDL-64E scan takes about as long as processing it (35 vs 40 ms); this way they overlap.
class ScanPrefetcher {
 public:
  ScanPrefetcher(DriveSource& source, size_t max_scans, size_t depth)
      : source_(source), max_scans_(max_scans), depth_(depth), thread_([this] { run(); }) {}
  ~ScanPrefetcher() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }
  /// The next scan in order; false at the end of the drive (or after max_scans).
  bool next(DriveScan& scan) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return !queue_.empty() || done_; });
    if (queue_.empty()) return false;
    scan = std::move(queue_.front());
    queue_.pop_front();
    changed_.notify_all();
    return true;
  }

 private:
  void run() {
    for (size_t i = 0; i < max_scans_; ++i) {
      DriveScan scan;
      if (!source_.next(scan)) break;
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [this] { return queue_.size() < depth_ || stop_; });
      if (stop_) break;
      queue_.push_back(std::move(scan));
      changed_.notify_all();
    }
    std::lock_guard<std::mutex> lock(mutex_);
    done_ = true;
    changed_.notify_all();
  }

  DriveSource& source_;
  const size_t max_scans_, depth_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<DriveScan> queue_;
  bool done_ = false, stop_ = false;
  std::thread thread_;  ///< last: starts once everything above exists
};

void progress(size_t done, size_t total) {
  if (total == 0 || (done % 10 != 0 && done != total)) return;
  const int width = 40;
  const int filled = static_cast<int>(width * done / total);
  std::cerr << "\r[" << std::string(filled, '#') << std::string(width - filled, ' ') << "] " << done
            << "/" << total << (done == total ? "\n" : "") << std::flush;
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

  std::unique_ptr<DriveSource> drive;
  if (args.count("kitti-raw")) {
    // simulate_urban writes sim_info.json two levels above the drive folder.
    std::filesystem::path drive_dir = std::filesystem::absolute(args["kitti-raw"]);
    if (drive_dir.filename().empty()) drive_dir = drive_dir.parent_path();  // "DRIVE/"
    if (!args.count("config") &&
        std::filesystem::exists(drive_dir.parent_path().parent_path() / "sim_info.json"))
      std::cerr << "offline_slam: note: " << drive_dir.string()
                << " was written by simulate_urban, whose prior misplaces every building on its "
                   "own; its overrides are --config config/sim.yaml (using config/kitti.yaml)\n";
    auto kitti = std::make_unique<KittiRawSource>();
    if (!kitti->open(args["kitti-raw"], argOr(args, "calib-dir", ""), &error)) {
      std::cerr << "offline_slam: " << error << "\n";
      return 1;
    }
    drive = std::move(kitti);
  } else if (args.count("scans")) {
    auto folder = std::make_unique<ScanFolderSource>();
    if (!folder->open(args, &error)) {
      std::cerr << "offline_slam: " << error << "\n";
      return 1;
    }
    drive = std::move(folder);
  } else {
    BagDriveTopics topics;
    topics.cloud = argOr(args, "cloud-topic", topics.cloud);
    topics.gps = argOr(args, "gps-topic", topics.gps);
    topics.imu = argOr(args, "imu-topic", topics.imu);
    topics.ground_truth = argOr(args, "ground-truth-topic", topics.ground_truth);
    topics.base_frame = argOr(args, "base-frame", topics.base_frame);
    auto bag = std::make_unique<BagSource>();
    if (!bag->open(args["bag"], topics, &error)) {
      std::cerr << "offline_slam: " << error << "\n";
      return 1;
    }
    drive = std::move(bag);
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
  ScanPrefetcher prefetcher(*drive, n, 8);
  auto readScan = [&] {
    const auto t0 = std::chrono::steady_clock::now();
    const bool ok = prefetcher.next(scan);
    pipeline.addInputTime(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    return ok;
  };
  for (size_t i = 0; i < n && readScan(); ++i) {
    if (!scan.cloud) {
      std::cerr << "\noffline_slam: " << scan.error << " (scan skipped)\n";
      continue;
    }
    if (scan.truth) truth_by_stamp[scan.stamp] = *scan.truth;
    pipeline.processScan(scan.stamp, scan.cloud,
                         use_imu ? scan.roll_pitch : std::optional<Eigen::Vector2d>(), scan.gnss,
                         use_imu ? scan.orientation : std::optional<Eigen::Quaterniond>());
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
