// Rostest node for localization.test (issue 21): the localization nodelet of
// launch/localization.launch localises a replayed bag on a saved map and recovers after a kidnap.
//
// Fixture, generated at test time into the build tree (a lock-protected cache keyed by the
// commands and the tools' stamps; nothing committed): simulate_urban drives 25 s through the
// Karlsruhe extract (seed 1, HDL-64E, exact GNSS/INS) and offline_slam --no-osm turns it into a
// map package; a second drive over the same roads (same route, 6 instead of 8 m/s, an Ouster
// OS1-64 instead of the HDL-64E: other scans from other places) becomes a bag with kitti2bag.
//
// The launch file's localization nodelet has no map (map_dir is only known here): this node
// unloads it and loads the same type as /localization_test with a copy of its parameters and the
// map, replays the bag with `rosbag play --clock`, and at kidnap_at seconds into the drive
// publishes /initialpose at a map keyframe kidnap_distance away from the vehicle (the filter is
// carried off). Asserted: the error while tracking against the bag's ground truth, the share of
// scans localised, the divergence detected and a correct re-localisation within the drive time
// limits, TF map -> base_link agreeing with odom.
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <cctype>
#include <functional>
#include <mutex>

#include "osm_graph_slam/LocalizationReport.h"
#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "osm_graph_slam/localization/map_frames.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/ros/conversions.h"
#include "slam_regression_common.h"

namespace osm_graph_slam {
namespace {

using namespace regression;

struct Sample {
  double stamp;
  std::string state;
  bool localized, diverged;
  Eigen::Isometry3d pose;
};

struct Fixture {
  fs::path dir;
  std::string bag, map_dir;
  std::shared_ptr<MapPackage> map;
  Eigen::Isometry3d drive_to_map = Eigen::Isometry3d::Identity();
  std::unique_ptr<BagDriveReader> truth;
  std::mutex mutex;
  std::vector<Sample> samples;
  size_t odom_messages = 0;
  nav_msgs::Odometry last_odom;
  double kidnap_stamp = -1.0;
  double kidnap_jump = 0.0;
  double first_stamp = -1.0;
  std::string error;
};
Fixture* R = nullptr;

/// The map drive and offline_slam's map package, the localised drive's bag; from the cache when
/// the commands and tools are unchanged.
std::string prepareFixture(Fixture& r) {
  ros::NodeHandle pnh("~");
  r.dir = cacheDir(pnh, "localization_test_data");
  std::error_code ec;
  FileLock lock(r.dir / "lock");
  if (!lock.ok()) return "cannot lock " + (r.dir / "lock").string();
  const std::string osm =
      pnh.param("osm", test::sharedDataPath("osm/2011_09_26_drive_0005_sync.osm"));
  const int map_scans = pnh.param("map_scans", 250);
  const int drive_scans = pnh.param("drive_scans", 200);
  const std::string world = fs::exists(osm) ? " --osm '" + osm + "'" : std::string();
  const std::string common = " --seed 1 --length 300 --motion-distortion --rtk" + world;
  const std::string sim_map = "'" + toolPath("simulate_urban") + "' --out '" +
                              (r.dir / "sim_map").string() + "' --scans " +
                              std::to_string(map_scans) + common;
  const std::string sim_drive = "'" + toolPath("simulate_urban") + "' --out '" +
                                (r.dir / "sim_drive").string() + "' --scans " +
                                std::to_string(drive_scans) + " --speed 6 --sensor os1_64" + common;
  const std::string key = sim_map + "\n" + sim_drive + "\n" +
                          fileStamp(toolPath("simulate_urban")) + fileStamp(toolPath("kitti2bag")) +
                          fileStamp(toolPath("offline_slam")) +
                          (world.empty() ? "" : fileStamp(osm));
  r.bag = (r.dir / "drive.bag").string();
  r.map_dir = (r.dir / "map" / "map_package").string();
  if (readText(r.dir / "key.txt") == key && fs::exists(r.bag) && fs::exists(r.map_dir)) {
    std::cout << "[localization_test] fixture from the cache " << r.dir << std::endl;
    return "";
  }
  const auto t0 = std::chrono::steady_clock::now();
  fs::remove(r.dir / "key.txt", ec);
  for (const char* d : {"sim_map", "sim_drive", "map"}) fs::remove_all(r.dir / d, ec);
  fs::remove(r.bag, ec);
  const fs::path log = r.dir / "generation.log";
  fs::remove(log, ec);
  const auto driveDir = [&](const fs::path& sim) -> std::string {
    const nlohmann::json info =
        nlohmann::json::parse(readText(sim / "sim_info.json"), nullptr, false);
    if (info.is_discarded() || !info.contains("drive_dir")) return "";
    return (sim / info["drive_dir"].get<std::string>()).string();
  };
  if (runLogged(sim_map, log) != 0) return "simulate_urban (map drive) failed:\n" + readText(log);
  const std::string map_drive = driveDir(r.dir / "sim_map");
  if (map_drive.empty()) return "simulate_urban wrote no usable sim_info.json (map drive)";
  if (runLogged("'" + toolPath("offline_slam") + "' --kitti-raw '" + map_drive + "' --config '" +
                    test::sourceDir() + "/config/sim.yaml' --no-osm --output '" +
                    (r.dir / "map").string() + "'",
                log) != 0)
    return "offline_slam failed:\n" + readText(log);
  fs::remove_all(r.dir / "sim_map", ec);  // the map package holds what localisation needs
  if (runLogged(sim_drive, log) != 0) return "simulate_urban (drive) failed:\n" + readText(log);
  const std::string drive = driveDir(r.dir / "sim_drive");
  if (drive.empty()) return "simulate_urban wrote no usable sim_info.json (drive)";
  if (runLogged("'" + toolPath("kitti2bag") + "' '" + drive + "' '" + r.bag + "'", log) != 0)
    return "kitti2bag failed:\n" + readText(log);
  fs::remove_all(r.dir / "sim_drive", ec);
  std::ofstream(r.dir / "key.txt.tmp") << key;
  fs::rename(r.dir / "key.txt.tmp", r.dir / "key.txt", ec);
  std::cout << "[localization_test] generated the fixture in "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s"
            << std::endl;
  return "";
}

/// The truth of the localised drive in the map frame at stamp.
std::optional<Eigen::Isometry3d> truthAt(double stamp) {
  const auto t = R->truth->groundTruthAt(std::llround(stamp * 1e9), 0.02);
  if (!t) return std::nullopt;
  return R->drive_to_map * *t;
}

void onStatus(const LocalizationReport::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(R->mutex);
  if (R->first_stamp < 0) R->first_stamp = msg->header.stamp.toSec();
  R->samples.push_back({msg->header.stamp.toSec(), msg->state, bool(msg->localized),
                        bool(msg->diverged), fromPoseMsg(msg->pose.pose)});
}

void onOdom(const nav_msgs::Odometry::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(R->mutex);
  ++R->odom_messages;
  R->last_odom = *msg;
}

/// Carries the filter off: /initialpose at the map keyframe whose distance from the vehicle's
/// true position is nearest to `distance`, with that keyframe's heading.
void kidnap(double stamp, double distance, ros::Publisher& pub) {
  const auto truth = truthAt(stamp);
  if (!truth) return;
  const MapKeyframe* best = nullptr;
  double best_gap = 1e9;
  for (const auto& kf : R->map->keyframes) {
    const double d = (kf.pose.translation() - truth->translation()).head<2>().norm();
    if (std::abs(d - distance) < best_gap) best_gap = std::abs(d - distance), best = &kf;
  }
  if (!best) return;
  geometry_msgs::PoseWithCovarianceStamped msg;
  msg.header.stamp = ros::Time(stamp);
  msg.header.frame_id = "map";
  msg.pose.pose = toPoseMsg(best->pose);
  pub.publish(msg);
  std::lock_guard<std::mutex> lock(R->mutex);
  R->kidnap_stamp = stamp;
  R->kidnap_jump = (best->pose.translation() - truth->translation()).head<2>().norm();
  std::cout << "[localization_test] kidnap at " << stamp << ": filter carried " << R->kidnap_jump
            << " m off" << std::endl;
}

class LocalizationRostest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    R = new Fixture;
    R->error = setUp();
  }
  static std::string setUp() {
    std::string error = prepareFixture(*R);
    if (!error.empty()) return error;
    R->map = std::make_shared<MapPackage>();
    if (!loadMapPackage(R->map_dir, *R->map, &error)) return error;
    R->truth = std::make_unique<BagDriveReader>();
    if (!R->truth->open(R->bag, {}, &error)) return error;
    const auto fix = R->truth->firstFix();
    if (!fix || !R->map->has_origin) return "no first fix in the bag or no origin in the map";
    R->drive_to_map =
        enuToEnu(EnuConverter(fix->lat, fix->lon, fix->alt),
                 EnuConverter(R->map->origin_lat, R->map->origin_lon, R->map->origin_alt));
    std::string manager = "/localization_manager";
    ros::NodeHandle("~").param("manager", manager, manager);
    // The launch file's localization nodelet has no map: one with the fixture's map instead.
    error = swapNodelet(manager, "/localization", "osm_graph_slam/LocalizationNodelet", "map_dir",
                        R->map_dir);
    if (!error.empty()) return error;
    ros::NodeHandle nh;
    ros::Subscriber status_sub = nh.subscribe("localization/status", 100, onStatus);
    ros::Subscriber odom_sub = nh.subscribe("odom", 100, onOdom);
    ros::Publisher initial =
        nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("/initialpose", 1, true);
    // The map is loaded once its points are published (latched).
    std::atomic<bool> map_ready{false};
    ros::Subscriber map_points = nh.subscribe<sensor_msgs::PointCloud2>(
        "localization/map_points", 1,
        boost::function<void(const sensor_msgs::PointCloud2::ConstPtr&)>(
            [&map_ready](const sensor_msgs::PointCloud2::ConstPtr&) { map_ready = true; }));
    if (!waitFor([&] { return map_ready.load(); }, 60.0))
      return "the localization nodelet published no map (did it load " + R->map_dir + "?)";

    tf2_ros::Buffer tf_buffer;
    tf2_ros::TransformListener tf_listener(tf_buffer);
    const double kidnap_at = param("kidnap_at", 9.0);
    const double kidnap_distance = param("kidnap_distance", 40.0);
    error = playBag(
        R->bag, param("play_rate", 1.0), (R->dir / "rosbag_play.log").string(),
        [&] {
          double first = -1, last = -1, kidnapped = -1;
          {
            std::lock_guard<std::mutex> lock(R->mutex);
            first = R->first_stamp;
            last = R->samples.empty() ? -1 : R->samples.back().stamp;
            kidnapped = R->kidnap_stamp;
          }
          if (kidnapped < 0 && first > 0 && last - first >= kidnap_at)
            kidnap(last, kidnap_distance, initial);
        },
        param("replay_timeout", 120.0));
    if (!error.empty()) return error;
    ros::WallDuration(1.0).sleep();  // the last scans through the nodelets
    // TF map -> base_link (map -> odom -> base_link) agrees with the last odom message.
    std::lock_guard<std::mutex> lock(R->mutex);
    if (R->odom_messages == 0) return "no odom message";
    try {
      const auto t = tf_buffer.lookupTransform("map", "base_link", R->last_odom.header.stamp,
                                               ros::Duration(1.0));
      const Eigen::Isometry3d tf_pose = fromTransformMsg(t.transform);
      const Eigen::Isometry3d odom_pose = fromPoseMsg(R->last_odom.pose.pose);
      const double d = (tf_pose.translation() - odom_pose.translation()).norm();
      if (d > 0.01) return "TF map -> base_link is " + std::to_string(d) + " m from odom";
    } catch (const std::exception& e) {
      return std::string("no TF map -> base_link: ") + e.what();
    }
    return "";
  }
  void SetUp() override { ASSERT_TRUE(R->error.empty()) << R->error; }
};

TEST_F(LocalizationRostest, LocalisesTheBagAndRecoversFromTheKidnap) {
  std::lock_guard<std::mutex> lock(R->mutex);
  ASSERT_GT(R->samples.size(), 50u);
  ASSERT_GT(R->kidnap_stamp, 0.0) << "the kidnap was never sent";
  // Before the kidnap: error of every localised scan against the truth.
  size_t before = 0, localized_before = 0, tracking_before = 0;
  double sum_t = 0, max_t = 0, sum_yaw = 0, first_localized = -1;
  std::optional<double> detected, recovered;
  double sum_after = 0, max_after = 0;
  size_t after = 0;
  for (const Sample& s : R->samples) {
    const auto truth = truthAt(s.stamp);
    if (!truth) continue;
    const double e = (s.pose.translation() - truth->translation()).head<2>().norm();
    const double yaw = Eigen::AngleAxisd(truth->linear().transpose() * s.pose.linear()).angle();
    if (s.stamp < R->kidnap_stamp) {
      ++before;
      if (!s.localized) continue;
      if (first_localized < 0) first_localized = s.stamp;
      ++localized_before;
      if (s.state != "tracking") continue;
      ++tracking_before;
      sum_t += e, sum_yaw += yaw, max_t = std::max(max_t, e);
    } else {
      if (s.diverged && !detected) detected = s.stamp - R->kidnap_stamp;
      if (detected && s.state == "relocalized" && !recovered) {
        recovered = s.stamp - R->kidnap_stamp;
        EXPECT_LT(e, 0.5) << "re-localised to a wrong place";
        EXPECT_LT(yaw, 2.0 * M_PI / 180.0);
      }
      if (recovered && s.state == "tracking") {
        ++after;
        sum_after += e;
        max_after = std::max(max_after, e);
      }
    }
  }
  // The states after the kidnap, one letter a scan (diagnosis): Tracking, Predicted,
  // Uninitialized, Relocalized, Off map; D: declared diverged.
  std::string states;
  for (const Sample& s : R->samples)
    if (s.stamp >= R->kidnap_stamp) states += s.diverged ? 'D' : char(std::toupper(s.state[0]));
  std::printf("[localization_test] after the kidnap: %s\n", states.c_str());
  const double mean_t = tracking_before ? sum_t / tracking_before : 1e9;
  const double mean_yaw_deg = tracking_before ? sum_yaw / tracking_before * 180 / M_PI : 1e9;
  std::printf(
      "[localization_test] %zu status messages, %zu odom; before the kidnap: %zu scans, first "
      "localised after %.1f s, %zu localised, %zu tracking: error mean %.3f m (max %.3f), "
      "heading %.3f deg; kidnap %.1f m: detected after %.1f s, re-localised after %.1f s; after: "
      "%zu tracking, error mean %.3f m (max %.3f)\n",
      R->samples.size(), R->odom_messages, before, first_localized - R->first_stamp,
      localized_before, tracking_before, mean_t, max_t, mean_yaw_deg, R->kidnap_jump,
      detected.value_or(-1), recovered.value_or(-1), after, after ? sum_after / after : -1.0,
      max_after);
  std::fflush(stdout);
  // Global localisation from the first scans (no initial pose), then tracking.
  EXPECT_LT(first_localized - R->first_stamp, param("max_first_localized_s", 3.0));
  EXPECT_GE(double(tracking_before), param("min_tracking_share", 0.7) * double(before));
  EXPECT_LT(mean_t, param("max_mean_error_m", 0.15));
  EXPECT_LT(max_t, param("max_error_m", 0.5));
  EXPECT_LT(mean_yaw_deg, param("max_mean_heading_deg", 0.5));
  // Kidnap: detected, then a correct re-localisation, then tracking again.
  EXPECT_GT(R->kidnap_jump, 30.0);
  ASSERT_TRUE(detected.has_value()) << "the kidnap was not detected";
  ASSERT_TRUE(recovered.has_value()) << "no re-localisation after the kidnap";
  EXPECT_LT(*recovered, param("max_recovery_s", 4.0));
  EXPECT_GT(after, 10u);
  EXPECT_LT(after ? sum_after / after : 1e9, param("max_mean_error_m", 0.15));
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  return osm_graph_slam::regression::rostestMain(argc, argv, "localization_test");
}
