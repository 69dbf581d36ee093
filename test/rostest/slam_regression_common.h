#pragma once
// Shared by the rostest nodes (slam_regression_offline, slam_regression_nodelets, localization):
// the simulated drive, generated once per build tree at test time and reused (a lock-protected
// cache), offline_slam runs, and the accuracy evaluation against the simulator's truth.
//
// The drive: simulate_urban through the Karlsruhe extract of ../shared/data (the procedural city
// when it is absent), HDL-64E with motion distortion and KITTI's intrinsic calibration errors
// (a perfect simulated sensor gives odometry almost no drift), cut after N scans, then kitti2bag.
// The raw KITTI folder is deleted once the bag exists; only drive.bag, prior.osm,
// buildings_true.geojson and sim_info.json stay in the cache.
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nodelet/NodeletLoad.h>
#include <nodelet/NodeletUnload.h>
#include <pcl/io/pcd_io.h>
#include <ros/init.h>
#include <ros/node_handle.h>
#include <ros/ros.h>
#include <ros/time.h>

#include "osm_graph_slam/eval/slam_evaluation.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "test_data.h"

namespace osm_graph_slam::regression {

namespace fs = std::filesystem;

/// A double test parameter from the node's private namespace (the .test file's <param>).
inline double param(const std::string& name, double fallback) {
  double v = fallback;
  ros::NodeHandle("~").param(name, v, fallback);
  return v;
}

/// Polls done() every 50 ms until it holds or `seconds` of wall time have passed.
inline bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.05).sleep();
  }
  return done();
}

struct DriveOptions {
  int scans = 600;        ///< 60 s at 10 Hz
  double length = 400.0;  ///< route length asked of the simulator [m]
  int seed = 1;
  std::string osm;     ///< extract; empty or missing: the procedural city
  fs::path cache_dir;  ///< where the drive is kept (created)
};

struct Drive {
  fs::path dir;
  std::string bag, prior_osm, buildings_true, world;
  bool generated = false;  ///< false: taken from the cache
  double seconds = 0.0;    ///< generation time (0 when cached)
  std::string error;
};

inline std::string toolPath(const std::string& name) {
  // Tools and rostest nodes share build_ws/devel/lib/osm_graph_slam.
  return (fs::read_symlink("/proc/self/exe").parent_path() / name).string();
}

/// Runs a shell command with its output appended to log; returns the exit code.
inline int runLogged(const std::string& command, const fs::path& log) {
  std::cout << "[slam_regression] $ " << command << std::endl;
  const int status = std::system((command + " >> '" + log.string() + "' 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

inline std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline std::string fileStamp(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "missing";
  return std::to_string(st.st_size) + "@" + std::to_string(st.st_mtim.tv_sec) + "." +
         std::to_string(st.st_mtim.tv_nsec);
}

/// Holds an exclusive flock on a file while alive (the other regression test waits).
class FileLock {
 public:
  explicit FileLock(const fs::path& path) : fd_(::open(path.c_str(), O_CREAT | O_RDWR, 0644)) {
    if (fd_ >= 0) ::flock(fd_, LOCK_EX);
  }
  ~FileLock() {
    if (fd_ >= 0) {
      ::flock(fd_, LOCK_UN);
      ::close(fd_);
    }
  }
  bool ok() const { return fd_ >= 0; }

 private:
  int fd_;
};

/// The test node's cache folder (private parameter cache_dir, default OGS_BINARY_DIR/name),
/// created; the caller locks it (FileLock on dir/"lock") while it fills it.
inline fs::path cacheDir(const ros::NodeHandle& pnh, const std::string& name) {
  const fs::path dir = pnh.param("cache_dir", std::string(OGS_BINARY_DIR) + "/" + name);
  std::error_code ec;
  fs::create_directories(dir, ec);
  return dir;
}

/// The drive both regression tests share, from the test node's private parameters.
inline DriveOptions driveOptionsFromParams(const ros::NodeHandle& pnh) {
  DriveOptions o;
  o.scans = pnh.param("scans", o.scans);
  o.length = pnh.param("route_length", o.length);
  o.osm = pnh.param("osm", test::sharedDataPath("osm/2011_09_26_drive_0005_sync.osm"));
  o.cache_dir = cacheDir(pnh, "slam_regression_data");
  return o;
}

/// The drive from the cache, or generated into it (under the lock). The cache key holds the
/// options and the simulator/kitti2bag binaries and extract (size and mtime): a rebuilt tool
/// regenerates the drive.
inline Drive prepareDrive(const DriveOptions& o) {
  Drive d;
  d.dir = o.cache_dir;
  std::error_code ec;
  FileLock lock(d.dir / "lock");
  if (!lock.ok()) {
    d.error = "cannot lock " + (d.dir / "lock").string();
    return d;
  }
  const bool have_extract = !o.osm.empty() && fs::exists(o.osm);
  d.world = have_extract ? o.osm : "procedural city";
  std::ostringstream sim_cmd;
  sim_cmd << "'" << toolPath("simulate_urban") << "' --out '" << (d.dir / "sim").string()
          << "' --length " << o.length << " --scans " << o.scans << " --seed " << o.seed
          << " --motion-distortion --kitti-calibration-error --rtk";  // exact GNSS/INS
  if (have_extract) sim_cmd << " --osm '" << o.osm << "'";
  const std::string key = sim_cmd.str() + "\nsimulate_urban " +
                          fileStamp(toolPath("simulate_urban")) + "\nkitti2bag " +
                          fileStamp(toolPath("kitti2bag")) + "\nextract " +
                          (have_extract ? fileStamp(o.osm) : std::string("-")) + "\n";
  d.bag = (d.dir / "drive.bag").string();
  d.prior_osm = (d.dir / "sim" / "prior.osm").string();
  d.buildings_true = (d.dir / "sim" / "buildings_true.geojson").string();
  if (readText(d.dir / "key.txt") == key && fs::exists(d.bag) && fs::exists(d.prior_osm) &&
      fs::exists(d.buildings_true)) {
    std::cout << "[slam_regression] drive from the cache " << d.dir << std::endl;
    return d;
  }
  const auto t0 = std::chrono::steady_clock::now();
  fs::remove(d.dir / "key.txt", ec);
  fs::remove_all(d.dir / "sim", ec);
  fs::remove(d.bag, ec);
  const fs::path log = d.dir / "generation.log";
  fs::remove(log, ec);
  if (runLogged(sim_cmd.str(), log) != 0) {
    d.error = "simulate_urban failed:\n" + readText(log);
    return d;
  }
  const nlohmann::json info =
      nlohmann::json::parse(readText(d.dir / "sim" / "sim_info.json"), nullptr, false);
  if (info.is_discarded() || !info.contains("drive_dir")) {
    d.error = "simulate_urban wrote no usable sim_info.json";
    return d;
  }
  const fs::path drive_dir = d.dir / "sim" / info["drive_dir"].get<std::string>();
  if (runLogged("'" + toolPath("kitti2bag") + "' '" + drive_dir.string() + "' '" + d.bag + "'",
                log) != 0) {
    d.error = "kitti2bag failed:\n" + readText(log);
    return d;
  }
  // The raw scans are in the bag now; drop the folder (about as large as the bag).
  fs::remove_all(drive_dir.parent_path(), ec);
  std::ofstream(d.dir / "key.txt.tmp") << key;
  fs::rename(d.dir / "key.txt.tmp", d.dir / "key.txt", ec);
  d.generated = true;
  d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[slam_regression] generated the drive (" << d.world << ") in " << d.seconds
            << " s: " << fs::file_size(d.bag) / 1e6 << " MB bag, sim_info "
            << d.dir / "sim" / "sim_info.json" << std::endl;
  return d;
}

/// offline_slam on the drive's bag with the simulator's config; output into out (cleared).
/// extra: e.g. "--no-osm", "--osm FILE", "--overpass URL". Returns the exit code.
inline int runOfflineSlam(const Drive& d, const fs::path& out, const std::string& extra,
                          double* seconds = nullptr) {
  std::error_code ec;
  fs::remove_all(out, ec);
  fs::create_directories(out.parent_path(), ec);
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = runLogged("'" + toolPath("offline_slam") + "' --bag '" + d.bag + "' --output '" +
                               out.string() + "' --config '" + test::sourceDir() +
                               "/config/sim.yaml' " + extra,
                           out.string() + ".log");
  if (seconds)
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rc;
}

// ---------------------------------------------------------------------------------------------
// Evaluation
// ---------------------------------------------------------------------------------------------

inline bool loadBuildings(const std::string& path, std::vector<Building>& out, std::string* error) {
  if (path.size() > 8 && path.substr(path.size() - 8) == ".geojson") {
    BuildingFileResult r = readBuildingsGeoJson(path);
    if (!r.ok) {
      *error = r.error;
      return false;
    }
    out = std::move(r.buildings);
    return true;
  }
  OsmData data = readOsmFile(path);
  if (!data.ok) {
    *error = path + ": " + data.error;
    return false;
  }
  out = std::move(data.buildings);
  return true;
}

/// The numbers the targets are stated in.
struct RunMetrics {
  TrajectoryErrors slam, baseline;
  /// The baseline interpolated at the run's keyframe stamps, against the run's truth: RPE over
  /// the same steps. A run that drops keyframes (the nodelets on a loaded machine) has longer
  /// steps and so a larger RPE than a baseline with all of them; compared here step for step.
  TrajectoryErrors baseline_same_steps;
  /// The buildings SLAM observed (evaluateSlam's *_observed: tagged with robot<->building
  /// edges), in the prior and corrected: what the "at least halved" target is about.
  BuildingErrors before, after;
  /// Every building the run output (observed or not), in the prior and corrected.
  BuildingErrors output_before, output_after;
  BuildingErrors prior_all;  ///< every building of the prior
  size_t corrected_buildings = 0, moved_buildings = 0, overlapping_pairs = 0,
         prior_overlapping_pairs = 0;
};

/// run and baseline: output folders holding trajectory_tum.txt and ground_truth_tum.txt (the
/// truth at that run's keyframe stamps), run also buildings_corrected.geojson. Trajectories are
/// compared in the map frame as they are (the thesis' setting: no alignment).
inline bool evaluateRun(const Drive& d, const fs::path& run, const fs::path& baseline,
                        RunMetrics& m, std::string* error) {
  SlamEvaluationInput in;
  Trajectory baseline_estimate, baseline_truth;
  for (const auto& [path, target] :
       {std::pair<fs::path, Trajectory*>{run / "trajectory_tum.txt", &in.estimate},
        {run / "ground_truth_tum.txt", &in.ground_truth},
        {baseline / "trajectory_tum.txt", &baseline_estimate},
        {baseline / "ground_truth_tum.txt", &baseline_truth}}) {
    const TrajectoryReadResult r = readTrajectory(path.string());
    if (!r.ok) {
      *error = r.error;
      return false;
    }
    *target = r.trajectory;
  }
  const fs::path corrected = run / "buildings_corrected.geojson";
  std::vector<Building>& truth = in.buildings_true;
  std::vector<Building>& prior = in.buildings_prior;
  std::vector<Building>& after = in.buildings_corrected;
  if (!loadBuildings(d.buildings_true, truth, error) || !loadBuildings(d.prior_osm, prior, error) ||
      !loadBuildings(corrected.string(), after, error))
    return false;
  if (truth.empty() || after.empty()) {
    *error = "no true or no corrected building";
    return false;
  }
  const GeoPoint origin = truth.front().outline_geo.front();
  const EnuConverter enu(origin.lat, origin.lon);
  for (auto* set : {&truth, &prior, &after})
    for (auto& b : *set) enu.project(b);
  const SlamEvaluation e = evaluateSlam(in);
  m.slam = e.slam;
  // The baseline against the truth at its own keyframes (the two runs' keyframes may differ).
  m.baseline = evaluateTrajectory(baseline_estimate, baseline_truth, in.options);
  Trajectory resampled, resampled_truth;
  for (const StampedPose& truth_pose : in.ground_truth) {
    StampedPose p{truth_pose.stamp, Eigen::Isometry3d::Identity()};
    if (!interpolatePose(baseline_estimate, p.stamp, 5.0, p.pose)) continue;
    resampled.push_back(p);
    resampled_truth.push_back(truth_pose);
  }
  m.baseline_same_steps = evaluateTrajectory(resampled, resampled_truth, in.options);
  if (e.prior_observed) m.before = e.prior_observed->errors;
  if (e.corrected_observed) m.after = e.corrected_observed->errors;
  // "Before" is the prior of exactly the buildings the run output (the back-end received them).
  std::map<std::pair<int64_t, int>, const Building*> prior_by_id;
  for (const auto& b : prior) prior_by_id[{b.id, b.part}] = &b;
  std::vector<Building> before;
  for (const auto& b : after) {
    auto it = prior_by_id.find({b.id, b.part});
    if (it == prior_by_id.end()) continue;
    before.push_back(*it->second);
    double shift = 0.0;
    for (size_t i = 0; i < b.outline_enu.size() && i < it->second->outline_enu.size(); ++i)
      shift = std::max(shift, (b.outline_enu[i] - it->second->outline_enu[i]).norm());
    if (shift > 0.01) ++m.moved_buildings;
  }
  m.output_before = evaluateBuildings(before, truth);
  m.output_after = evaluateBuildings(after, truth);
  m.prior_all = evaluateBuildings(prior, truth);
  m.corrected_buildings = after.size();
  // No two output buildings may overlap, observed or not.
  m.overlapping_pairs = findOverlappingBuildings(after).size();
  m.prior_overlapping_pairs = findOverlappingBuildings(before).size();
  return true;
}

inline void printMetrics(const std::string& label, const RunMetrics& m) {
  auto traj = [](const char* name, const TrajectoryErrors& e) {
    std::printf(
        "  %-22s %4zu poses  ATE mean %.3f m (rmse %.3f, max %.3f)  RPE %.4f m, %.5f rad"
        "  KITTI %.2f %%\n",
        name, e.associated, e.ate.mean, e.ate.rmse, e.ate.max, e.rpe_trans.mean, e.rpe_rot.mean,
        e.kitti_trans_percent);
  };
  std::printf("[slam_regression] %s\n", label.c_str());
  traj("with OSM", m.slam);
  traj("without OSM (baseline)", m.baseline);
  traj("baseline, same steps", m.baseline_same_steps);
  std::printf("  ATE ratio %.3f, RPE ratio %.3f, rotational %.3f (same steps)\n",
              m.slam.ate.mean / m.baseline.ate.mean,
              m.slam.rpe_trans.mean / m.baseline_same_steps.rpe_trans.mean,
              m.slam.rpe_rot.mean / m.baseline_same_steps.rpe_rot.mean);
  std::printf(
      "  observed buildings: %zu; corner error prior %.3f m (max %.3f) -> corrected %.3f m "
      "(max %.3f), ratio %.3f; heading %.2f -> %.2f deg\n",
      m.after.matched, m.before.mean_corner_error, m.before.max_corner_error,
      m.after.mean_corner_error, m.after.max_corner_error,
      m.before.mean_corner_error > 0 ? m.after.mean_corner_error / m.before.mean_corner_error : 0.0,
      m.before.mean_heading_error_deg, m.after.mean_heading_error_deg);
  std::printf(
      "  all %zu output buildings (%zu moved by > 1 cm): corner error %.3f -> %.3f m; whole "
      "prior %.3f m over %zu; overlapping pairs %zu (same buildings in the prior: %zu)\n",
      m.corrected_buildings, m.moved_buildings, m.output_before.mean_corner_error,
      m.output_after.mean_corner_error, m.prior_all.mean_corner_error, m.prior_all.matched,
      m.overlapping_pairs, m.prior_overlapping_pairs);
  std::fflush(stdout);
}

/// Every file save_map writes parses and agrees with the others (gtest expectations); with
/// timing: also offline_slam's own files. Returns the number of keyframes (trajectory poses).
inline size_t expectSaveMapOutputsParse(const fs::path& out, bool with_buildings,
                                        bool offline_files) {
  pcl::PointCloud<pcl::PointXYZI> map;
  EXPECT_EQ(pcl::io::loadPCDFile((out / "map.pcd").string(), map), 0) << out / "map.pcd";
  EXPECT_GT(map.size(), 10000u);
  const TrajectoryReadResult tum = readTrajectory((out / "trajectory_tum.txt").string());
  const TrajectoryReadResult kitti = readTrajectory((out / "trajectory_kitti.txt").string());
  EXPECT_TRUE(tum.ok) << tum.error;
  EXPECT_TRUE(kitti.ok) << kitti.error;
  const size_t keyframes = tum.trajectory.size();
  EXPECT_GT(keyframes, 20u);
  EXPECT_EQ(kitti.trajectory.size(), keyframes);
  PoseGraph graph;
  const G2oReadResult g2o = readG2o((out / "graph.g2o").string(), &graph);
  EXPECT_TRUE(g2o.ok) << g2o.message;
  EXPECT_GE(size_t(g2o.num_vertices), keyframes);
  EXPECT_GE(size_t(g2o.num_edges), keyframes - 1);
  size_t buildings = 0;
  if (with_buildings) {
    const BuildingFileResult geo =
        readBuildingsGeoJson((out / "buildings_corrected.geojson").string());
    const OsmData osm = readOsmFile((out / "buildings_corrected.osm").string());
    EXPECT_TRUE(geo.ok) << geo.error;
    EXPECT_TRUE(osm.ok) << osm.error;
    buildings = geo.buildings.size();
    EXPECT_GE(buildings, 5u);
    EXPECT_EQ(osm.buildings.size(), buildings);
    EXPECT_GT(size_t(g2o.num_vertices), keyframes) << "no building vertex in graph.g2o";
  }
  if (offline_files) {
    for (const char* f : {"odometry_tum.txt", "ground_truth_tum.txt"}) {
      const TrajectoryReadResult r = readTrajectory((out / f).string());
      EXPECT_TRUE(r.ok) << r.error;
      EXPECT_EQ(r.trajectory.size(), keyframes) << f;
    }
    const nlohmann::json timing =
        nlohmann::json::parse(readText(out / "timing.json"), nullptr, false);
    EXPECT_FALSE(timing.is_discarded()) << out / "timing.json";
    if (!timing.is_discarded()) {
      EXPECT_EQ(timing.value("keyframes", size_t(0)), keyframes);
      EXPECT_GT(timing.value("scans_per_second", 0.0), 0.0);
    }
    EXPECT_NE(readText(out / "timing.txt").find("scans/s"), std::string::npos);
  }
  std::printf(
      "[slam_regression] %s: map.pcd %zu points, %zu keyframes, %zu buildings, graph.g2o "
      "%d vertices / %d edges\n",
      out.string().c_str(), map.size(), keyframes, buildings, g2o.num_vertices, g2o.num_edges);
  return keyframes;
}

/// Plays a bag with its clock (`rosbag play --clock -q -d 1 -r rate -s start_s`) in a child
/// process, its output in log; calls tick() while it plays. "" when it finished, else why not (a
/// timeout stops it with SIGINT).
inline std::string playBag(const std::string& bag, double rate, const std::string& log,
                           const std::function<void()>& tick, double timeout_s,
                           double start_s = 0.0) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::freopen(log.c_str(), "w", stdout);
    std::freopen(log.c_str(), "a", stderr);
    const std::string r = std::to_string(rate), start = std::to_string(start_s);
    ::execl("/usr/bin/rosbag", "rosbag", "play", "--clock", "-q", "-d", "1", "-r", r.c_str(), "-s",
            start.c_str(), bag.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  if (pid < 0) return "fork failed";
  int status = 0;
  const bool done = waitFor(
      [&] {
        tick();
        return ::waitpid(pid, &status, WNOHANG) == pid;
      },
      timeout_s);
  if (!done) {
    ::kill(pid, SIGINT);
    ::waitpid(pid, &status, 0);
    return "rosbag play did not finish in time";
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return "rosbag play failed:\n" + readText(log);
  return "";
}

/// Loads a nodelet of `type` named `name` (its parameters already set) into `manager`.
inline std::string loadNodelet(const std::string& manager, const std::string& name,
                               const std::string& type,
                               const std::vector<std::pair<std::string, std::string>>& remaps) {
  if (!ros::service::waitForService(manager + "/load_nodelet", ros::Duration(60.0)))
    return "no nodelet manager " + manager;
  nodelet::NodeletLoad load;
  load.request.name = name;
  load.request.type = type;
  for (const auto& [from, to] : remaps) {
    load.request.remap_source_args.push_back(from);
    load.request.remap_target_args.push_back(to);
  }
  if (!ros::service::call(manager + "/load_nodelet", load) || !load.response.success)
    return "loading " + name + " failed";
  return "";
}

/// Replaces the launch file's nodelet `name` (e.g. "/localization") in `manager` by one of `type`
/// named name + "_test" with name's parameters and one of them set (`key` = `value`: a path only
/// known at test time), remapped as given (the launch file's remaps are not carried over).
inline std::string swapNodelet(
    const std::string& manager, const std::string& name, const std::string& type,
    const std::string& key, const std::string& value,
    const std::vector<std::pair<std::string, std::string>>& remaps = {}) {
  if (!ros::service::waitForService(manager + "/load_nodelet", ros::Duration(60.0)))
    return "no nodelet manager " + manager;
  XmlRpc::XmlRpcValue params;
  if (!waitFor([&] { return ros::param::get(name, params); }, 30.0) ||
      params.getType() != XmlRpc::XmlRpcValue::TypeStruct)
    return "no " + name + " parameters (was the launch file included?)";
  params[key] = value;
  ros::param::set(name + "_test", params);
  nodelet::NodeletUnload unload;
  unload.request.name = name;
  if (!waitFor(
          [&] {
            return ros::service::call(manager + "/unload_nodelet", unload) &&
                   unload.response.success;
          },
          60.0))
    return "could not unload the launch file's " + name;
  return loadNodelet(manager, name + "_test", type, remaps);
}

/// main() of a rostest node: gtest, ros::init as `node_name`, two spinner threads.
inline int rostestMain(int argc, char** argv, const char* node_name) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int rc = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return rc;
}

}  // namespace osm_graph_slam::regression
