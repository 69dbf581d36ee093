// Rostest node for slam_pipeline.test (issue 8): generates a short simulated drive (procedural
// city, 15 s at 10 Hz) in a temp dir, converts it with the kitti2bag library, serves the
// simulator's perturbed prior.osm with the Overpass test server, loads osm_buffer into the
// running manager and publishes the bag in lock-step (each scan after the previous one produced
// its scan-matching status and, for keyframes, its line segments) together with /clock. Then it
// checks the outputs of the whole pipeline, the TF tree, save_map / dump_graph and bad input.
//
// The tests share one drive and run in declaration order (gtest's default): before data, drive,
// TF, save_map, dump_graph / unwritable folder.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <nodelet/NodeletLoad.h>
#include <pcl/io/pcd_io.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <vector>

#include "map_server_reader.h"
#include "osm_graph_slam/BuildingArray.h"
#include "osm_graph_slam/DumpGraph.h"
#include "osm_graph_slam/FloorCoeffs.h"
#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/LineSegmentArray.h"
#include "osm_graph_slam/LoopClosure.h"
#include "osm_graph_slam/SaveMap.h"
#include "osm_graph_slam/ScanMatchingStatus.h"
#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/sim/simulator.h"
#include "overpass_server_fixture.h"
#include "test_data.h"

namespace fs = std::filesystem;

namespace osm_graph_slam {
namespace {

constexpr int kScans = 150;      // 15 s of driving at 10 Hz
constexpr double kMaxAte = 2.0;  // [m] absolute (no alignment) keyframe ATE against the truth

bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.02).sleep();
  }
  return done();
}

/// Everything the pipeline publishes that the tests look at.
struct Inbox {
  std::mutex mutex;
  int status = 0, failed_status = 0, odom = 0;
  std::vector<KeyFrame::ConstPtr> keyframes;  // cloud dropped after arrival
  std::map<uint64_t, size_t> segments;        // keyframe id -> number of segments
  BuildingArray::ConstPtr osm_buildings;
  int osm_messages = 0;
  std::vector<geometry_msgs::PoseStamped> poses;
  nav_msgs::Path::ConstPtr path;
  int path_messages = 0;
  ros::WallTime last_path_time;
  BuildingArray::ConstPtr slam_buildings;
  int loops = 0;
  std::vector<FloorCoeffs::ConstPtr> floors;
  nav_msgs::OccupancyGrid::ConstPtr grid_map;
  int grid_messages = 0;

  template <typename F>
  auto locked(F f) {
    std::lock_guard<std::mutex> lock(mutex);
    return f();
  }
};

/// Shared by all tests: the generated drive, the server, subscribers and publishers.
struct Pipeline {
  fs::path dir;
  std::string bag_path, prior_osm;
  sim::SimulationStats sim_stats;
  std::unique_ptr<test::OverpassTestServer> server;
  std::unique_ptr<ros::NodeHandle> nh;
  Inbox inbox;
  std::vector<ros::Subscriber> subs;
  ros::Publisher clock_pub, cloud_pub, fix_pub, imu_pub, loop_pub, segments_pub;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_tf;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener;
  std::vector<sensor_msgs::PointCloud2::ConstPtr> clouds;
  std::vector<sensor_msgs::NavSatFix::ConstPtr> fixes;
  std::vector<sensor_msgs::Imu::ConstPtr> imus;
  Trajectory ground_truth;  // base_link in ENU at the first fix (= the map frame)
  std::string setup_error;
  bool osm_loaded = false, drive_done = false;
  double drive_seconds = 0.0, generation_seconds = 0.0;
  size_t bad_input_path_messages = 0, bad_input_keyframes = 0;
};

Pipeline* P = nullptr;

std::string managerName() {
  std::string manager = "/osm_graph_slam_manager";
  ros::NodeHandle("~").param("manager", manager, manager);
  return manager;
}

void publishClock(const ros::Time& t) {
  rosgraph_msgs::Clock c;
  c.clock = t;
  P->clock_pub.publish(c);
}

void subscribe() {
  ros::NodeHandle& nh = *P->nh;
  Inbox& in = P->inbox;
  P->subs.push_back(nh.subscribe<ScanMatchingStatus>("scan_matching_status", 50,
                                                     [&in](const ScanMatchingStatus::ConstPtr& m) {
                                                       in.locked([&] {
                                                         ++in.status;
                                                         if (m->failed) ++in.failed_status;
                                                         return 0;
                                                       });
                                                     }));
  P->subs.push_back(nh.subscribe<nav_msgs::Odometry>(
      "odom", 50,
      [&in](const nav_msgs::Odometry::ConstPtr&) { in.locked([&] { return ++in.odom; }); }));
  P->subs.push_back(nh.subscribe<KeyFrame>("keyframe", 50, [&in](const KeyFrame::ConstPtr& m) {
    auto light = boost::make_shared<KeyFrame>(*m);
    light->cloud.data.clear();
    in.locked([&] {
      in.keyframes.push_back(light);
      return 0;
    });
  }));
  P->subs.push_back(
      nh.subscribe<FloorCoeffs>("floor_coeffs", 50, [&in](const FloorCoeffs::ConstPtr& m) {
        in.locked([&] {
          in.floors.push_back(m);
          return 0;
        });
      }));
  P->subs.push_back(nh.subscribe<LineSegmentArray>(
      "line_segments", 50, [&in](const LineSegmentArray::ConstPtr& m) {
        in.locked([&] { return in.segments[m->keyframe_id] = m->segments.size(); });
      }));
  P->subs.push_back(
      nh.subscribe<BuildingArray>("osm/buildings", 10, [&in](const BuildingArray::ConstPtr& m) {
        in.locked([&] {
          in.osm_buildings = m;
          return ++in.osm_messages;
        });
      }));
  P->subs.push_back(nh.subscribe<geometry_msgs::PoseStamped>(
      "slam/pose", 100, [&in](const geometry_msgs::PoseStamped::ConstPtr& m) {
        in.locked([&] {
          in.poses.push_back(*m);
          return 0;
        });
      }));
  P->subs.push_back(
      nh.subscribe<nav_msgs::Path>("slam/path", 10, [&in](const nav_msgs::Path::ConstPtr& m) {
        in.locked([&] {
          in.path = m;
          in.last_path_time = ros::WallTime::now();
          return ++in.path_messages;
        });
      }));
  P->subs.push_back(nh.subscribe<nav_msgs::OccupancyGrid>(
      "slam/grid_map", 2, [&in](const nav_msgs::OccupancyGrid::ConstPtr& m) {
        in.locked([&] {
          in.grid_map = m;
          return ++in.grid_messages;
        });
      }));
  P->subs.push_back(
      nh.subscribe<BuildingArray>("slam/buildings", 10, [&in](const BuildingArray::ConstPtr& m) {
        in.locked([&] {
          in.slam_buildings = m;
          return 0;
        });
      }));
  P->subs.push_back(nh.subscribe<LoopClosure>(
      "loop_closures", 10,
      [&in](const LoopClosure::ConstPtr&) { in.locked([&] { return ++in.loops; }); }));
}

/// Short drive in a small procedural city -> KITTI raw folder -> bag (the kitti2bag library).
bool generateDrive(std::string* error) {
  const auto t0 = std::chrono::steady_clock::now();
  sim::SimulationParams params;
  params.seed = 1;
  // The default city (7 x 6 blocks) and seed: the drive starts between buildings, so the first
  // keyframe's walls can set the initial heading by global matching.
  params.route.length = 400.0;
  params.max_scans = kScans;
  params.nav.rtk = true;  // exact GNSS/INS, as the test's limits were measured with
  sim::UrbanSimulator simulator;
  if (!simulator.build(params, error)) return false;
  const fs::path out = P->dir / "sim";
  if (!simulator.writeDataset(out.string(), P->sim_stats, {}, error)) return false;
  P->prior_osm = (out / "prior.osm").string();
  KittiRawBagOptions bag;
  bag.drive_dir = P->sim_stats.drive_dir;
  bag.bag_path = (P->dir / "drive.bag").string();
  const BagConversionResult r = convertKittiRawToBag(bag);
  if (!r.ok) {
    *error = "kitti2bag: " + r.error;
    return false;
  }
  P->bag_path = bag.bag_path;
  // The raw drive is no longer needed (only the bag and prior.osm are).
  fs::remove_all(out / "2020_01_01");
  P->generation_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[slam_pipeline] simulated " << r.clouds << " scans, route "
            << P->sim_stats.route_length_m << " m, " << P->sim_stats.buildings
            << " buildings, prior: " << P->sim_stats.prior_perturbed << " perturbed, "
            << P->sim_stats.prior_removed << " removed, " << P->sim_stats.prior_phantom
            << " phantoms; generation + bag " << P->generation_seconds << " s"
            << std::endl;  // flushed before the server forks
  return true;
}

/// The bag's messages in memory (the replay publishes them in lock-step); tf_static sent now.
bool readBag(std::string* error) {
  rosbag::Bag bag(P->bag_path, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (auto c = m.instantiate<sensor_msgs::PointCloud2>()) P->clouds.push_back(c);
    if (auto f = m.instantiate<sensor_msgs::NavSatFix>()) P->fixes.push_back(f);
    if (auto i = m.instantiate<sensor_msgs::Imu>()) P->imus.push_back(i);
    if (auto g = m.instantiate<nav_msgs::Odometry>())
      P->ground_truth.push_back({g->header.stamp.toSec(), fromPoseMsg(g->pose.pose)});
    if (auto t = m.instantiate<tf2_msgs::TFMessage>()) P->static_tf->sendTransform(t->transforms);
  }
  bag.close();
  fs::remove(P->bag_path);
  if (P->clouds.size() != size_t(kScans) || P->fixes.size() != P->clouds.size() ||
      P->imus.empty() || P->ground_truth.size() != P->clouds.size()) {
    *error = "unexpected bag content: " + std::to_string(P->clouds.size()) + " clouds, " +
             std::to_string(P->fixes.size()) + " fixes, " + std::to_string(P->imus.size()) +
             " imu, " + std::to_string(P->ground_truth.size()) + " ground truth";
    return false;
  }
  return true;
}

bool loadNodelet(const std::string& name, const std::string& type, std::string* error) {
  const std::string manager = managerName();
  if (!ros::service::waitForService(manager + "/load_nodelet", ros::Duration(60.0))) {
    *error = "no nodelet manager " + manager;
    return false;
  }
  nodelet::NodeletLoad load;
  load.request.name = name;
  load.request.type = type;
  if (!ros::service::call(manager + "/load_nodelet", load) || !load.response.success) {
    *error = "loading " + name + " into " + manager + " failed";
    return false;
  }
  return true;
}

/// Starts the Overpass test server on prior.osm, loads osm_buffer pointed at it and
/// graph_backend (with the first IMU heading as the known initial heading, if asked).
bool loadNodelets(std::string* error) {
  P->server = std::make_unique<test::OverpassTestServer>(
      test::sourceDir() + "/scripts/overpass_test_server.py", P->prior_osm);
  if (!P->server->start()) {
    *error = "the Overpass test server did not start";
    return false;
  }
  ros::NodeHandle& nh = *P->nh;
  double query_radius = 0.0;
  if (!nh.getParam("/osm_buffer/query_radius", query_radius) ||
      !nh.hasParam("/graph_backend/mode")) {
    *error = "config/osm_buffer.yaml or config/graph_backend.yaml was not loaded";
    return false;
  }
  nh.setParam("/osm_buffer/source", "overpass");
  nh.setParam("/osm_buffer/overpass_url", P->server->url());
  bool heading_from_imu = true;
  ros::NodeHandle("~").param("initial_heading_from_imu", heading_from_imu, heading_from_imu);
  if (heading_from_imu) {
    const auto& q = P->imus.front()->orientation;
    const double yaw =
        std::atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z));
    nh.setParam("/graph_backend/initial_yaw_known", true);
    nh.setParam("/graph_backend/initial_yaw", yaw);
    std::cout << "[slam_pipeline] initial heading from imu/data: " << yaw * 180.0 / M_PI
              << " deg\n";
  }
  return loadNodelet("/osm_buffer", "osm_graph_slam/OsmBufferNodelet", error) &&
         loadNodelet("/graph_backend", "osm_graph_slam/GraphBackendNodelet", error);
}

class SlamPipeline : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    P = new Pipeline;
    P->dir = fs::temp_directory_path() / ("ogs_slam_pipeline_" + std::to_string(::getpid()));
    fs::create_directories(P->dir);
    P->nh = std::make_unique<ros::NodeHandle>();
    ros::NodeHandle& nh = *P->nh;
    P->clock_pub = nh.advertise<rosgraph_msgs::Clock>("/clock", 10);
    P->cloud_pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", 5);
    P->fix_pub = nh.advertise<sensor_msgs::NavSatFix>("gps/fix", 10);
    P->imu_pub = nh.advertise<sensor_msgs::Imu>("imu/data", 10);
    P->loop_pub = nh.advertise<LoopClosure>("loop_closures", 10);
    P->segments_pub = nh.advertise<LineSegmentArray>("line_segments", 10);
    P->static_tf = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
    P->tf_buffer = std::make_unique<tf2_ros::Buffer>(ros::Duration(60.0));
    P->tf_listener = std::make_unique<tf2_ros::TransformListener>(*P->tf_buffer);
    subscribe();
    std::string error;
    if (!generateDrive(&error) || !readBag(&error) || !loadNodelets(&error)) P->setup_error = error;
  }
  static void TearDownTestSuite() {
    if (!P) return;
    P->server.reset();  // stops exactly the child it started
    std::error_code ec;
    fs::remove_all(P->dir, ec);
    delete P;
    P = nullptr;
  }
};

std::string saveMapService() {
  return "/graph_backend/save_map";
}

TEST_F(SlamPipeline, SaveMapBeforeAnyDataFails) {
  ASSERT_TRUE(P->setup_error.empty()) << P->setup_error;
  ASSERT_TRUE(ros::service::waitForService(saveMapService(), ros::Duration(60.0)))
      << "graph_backend did not come up";
  SaveMap srv;
  srv.request.destination = (P->dir / "too_early").string();
  srv.request.resolution = 0.5;
  ASSERT_TRUE(ros::service::call(saveMapService(), srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_NE(srv.response.message.find("no keyframe"), std::string::npos) << srv.response.message;
  EXPECT_TRUE(srv.response.files.empty());
}

TEST_F(SlamPipeline, Drive) {
  ASSERT_TRUE(P->setup_error.empty()) << P->setup_error;
  Inbox& in = P->inbox;
  ASSERT_TRUE(waitFor(
      [&] {
        return P->cloud_pub.getNumSubscribers() > 0 && P->fix_pub.getNumSubscribers() > 0 &&
               P->loop_pub.getNumSubscribers() > 0 && P->segments_pub.getNumSubscribers() > 0;
      },
      60.0))
      << "the nodelets did not subscribe";

  const auto& clouds = P->clouds;
  const auto& fixes = P->fixes;
  const auto& imus = P->imus;

  // Pre-roll: the clock runs up to the first scan while osm_buffer sets the origin from the first
  // fix and fetches its first buffer from the server (its timer runs on simulated time).
  const ros::Time t0 = clouds.front()->header.stamp;
  const auto start = std::chrono::steady_clock::now();
  ros::Time now = t0 - ros::Duration(30.0);
  publishClock(now);
  P->fix_pub.publish(fixes.front());
  for (int i = 0; i < 290 && in.locked([&] { return in.osm_messages; }) == 0; ++i) {
    now += ros::Duration(0.1);
    publishClock(now);
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_GT(in.locked([&] { return in.osm_messages; }), 0)
      << "no osm/buildings from the Overpass test server before the drive";

  for (size_t k = 0; k < clouds.size(); ++k) {
    const ros::Time stamp = clouds[k]->header.stamp;
    publishClock(stamp);
    P->fix_pub.publish(fixes[k]);
    if (k < imus.size()) P->imu_pub.publish(imus[k]);
    const int status_before = in.locked([&] { return in.status; });
    const size_t kf_before = in.locked([&] { return in.keyframes.size(); });
    P->cloud_pub.publish(clouds[k]);
    ASSERT_TRUE(waitFor([&] { return in.locked([&] { return in.status; }) > status_before; }, 90.0))
        << "no scan_matching_status for scan " << k;
    // Keyframes: wait for their wall segments too (lock-step through line_extraction).
    const auto kf = in.locked([&] {
      return in.keyframes.size() > kf_before ? in.keyframes.back() : KeyFrame::ConstPtr();
    });
    if (kf) {
      ASSERT_TRUE(
          waitFor([&] { return in.locked([&] { return in.segments.count(kf->id) != 0; }); }, 90.0))
          << "no line_segments for keyframe " << kf->id;
    }
    if (k == clouds.size() / 2) {
      // Bad input in the middle of the drive: a loop closure from the newest keyframe to one that
      // never existed, one from a keyframe that never comes, and segments of an unknown keyframe.
      const uint64_t newest = in.locked([&] { return in.keyframes.back()->id; });
      LoopClosure loop;
      loop.header.stamp = stamp;
      loop.from_id = newest;
      loop.to_id = 1000000;
      loop.relative_pose.orientation.w = 1.0;
      for (int i = 0; i < 6; ++i) loop.information[i * 7] = 100.0;
      P->loop_pub.publish(loop);
      loop.from_id = 2000000;
      loop.to_id = 0;
      P->loop_pub.publish(loop);
      LineSegmentArray segments;
      segments.header.stamp = stamp;
      segments.keyframe_id = 3000000;
      LineSegment s;
      s.end.x = 5.0;
      segments.segments.assign(4, s);
      P->segments_pub.publish(segments);
      P->bad_input_keyframes = in.locked([&] { return in.keyframes.size(); });
      P->bad_input_path_messages = in.locked([&] { return size_t(in.path_messages); });
    }
  }
  // Let the back-end catch up: every keyframe in the path, and no new path for two periods. The
  // keyframes are counted inside the wait: the last one may arrive after its scan's status.
  const bool caught_up = waitFor(
      [&] {
        return in.locked([&] { return in.path && in.path->poses.size() == in.keyframes.size(); });
      },
      120.0);
  ASSERT_TRUE(caught_up) << in.locked([&] {
    std::ostringstream why;
    why << "slam/path never held all " << in.keyframes.size() << " keyframes: the last of "
        << in.path_messages << " paths held " << (in.path ? in.path->poses.size() : 0)
        << ", published " << (ros::WallTime::now() - in.last_path_time).toSec() << " s ago";
    return why.str();
  });
  double period = 3.0;
  P->nh->param("/graph_backend/optimization_period", period, period);
  waitFor(
      [&] {
        return in.locked(
            [&] { return (ros::WallTime::now() - in.last_path_time).toSec() > 2.5 * period; });
      },
      60.0);
  P->drive_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  P->drive_done = true;

  std::lock_guard<std::mutex> lock(in.mutex);
  std::cout << "[slam_pipeline] drive: " << clouds.size() << " scans, " << in.keyframes.size()
            << " keyframes, " << in.failed_status << " failed scan matches, " << in.segments.size()
            << " segment arrays, " << in.osm_messages << " osm/buildings messages (last "
            << in.osm_buildings->buildings.size() << " buildings), " << in.loops
            << " loop closures, " << in.path_messages << " paths; lock-step replay "
            << P->drive_seconds << " s\n";
  EXPECT_EQ(in.status, kScans);
  EXPECT_EQ(in.odom, kScans - in.failed_status);
  EXPECT_LE(in.failed_status, 3);
  // One keyframe per 2 m (or 0.26 rad, or 2 s).
  EXPECT_GE(in.keyframes.size(), 35u);
  EXPECT_LE(in.keyframes.size(), 70u);
  for (size_t i = 0; i < in.keyframes.size(); ++i) EXPECT_EQ(in.keyframes[i]->id, i);
  size_t with_segments = 0;
  for (const auto& [id, n] : in.segments) with_segments += n >= 3 ? 1 : 0;
  EXPECT_GE(with_segments, in.keyframes.size() * 3 / 4) << "few keyframes with wall segments";
  // floor_detection answers every keyframe; the simulated road is 0.93 m below base_link and
  // tilts by at most ~3 deg.
  EXPECT_EQ(in.floors.size(), in.keyframes.size());
  size_t floors_ok = 0;
  for (const auto& f : in.floors)
    floors_ok += f->found && std::abs(f->coeffs[3] - 0.93) < 0.1 && f->coeffs[2] > 0.99 ? 1 : 0;
  EXPECT_GE(floors_ok, in.floors.size() * 9 / 10) << "few keyframes with the simulated floor";
  ASSERT_TRUE(in.osm_buildings);
  EXPECT_EQ(in.osm_buildings->header.frame_id, "map");
  EXPECT_GE(in.osm_buildings->buildings.size(), 5u);
  ASSERT_TRUE(in.slam_buildings);
  EXPECT_GE(in.slam_buildings->buildings.size(), 5u) << "no building entered the graph";
  EXPECT_EQ(in.path->header.frame_id, "map");
  EXPECT_GE(in.poses.size(), in.keyframes.size());
  // Bad input did not stop the pipeline: more keyframes and paths came after it.
  EXPECT_GT(in.keyframes.size(), P->bad_input_keyframes + 10);
  EXPECT_GT(size_t(in.path_messages), P->bad_input_path_messages);
}

TEST_F(SlamPipeline, TfTreeMatchesLatestPose) {
  ASSERT_TRUE(P->drive_done) << "the drive did not complete (see SlamPipeline.Drive)";
  Inbox& in = P->inbox;
  const auto path = in.locked([&] { return in.path; });
  ASSERT_FALSE(in.locked([&] { return in.poses.empty(); }));
  const auto last_pose = in.locked([&] { return in.poses.back(); });
  ASSERT_TRUE(path && !path->poses.empty());
  const geometry_msgs::PoseStamped& latest = path->poses.back();
  // slam/pose after an optimisation is the path's latest keyframe.
  EXPECT_EQ(last_pose.header.stamp, latest.header.stamp);
  EXPECT_EQ(last_pose.header.frame_id, "map");
  EXPECT_LT(
      (fromPoseMsg(last_pose.pose).translation() - fromPoseMsg(latest.pose).translation()).norm(),
      1e-6);
  // The latest map -> odom broadcast (graph_backend) after odom -> base_link (scan_matching) at
  // the latest keyframe's stamp equals that keyframe's corrected pose. map -> odom is stamped
  // with the time it was computed at, so it is looked up as the latest, not at the keyframe's
  // stamp (where it held the correction before the last optimisations). Waits on the wall
  // clock: the simulated clock stands still now, and tf2's own timeout runs on it.
  const Eigen::Isometry3d expected = fromPoseMsg(latest.pose);
  Eigen::Isometry3d err = Eigen::Isometry3d::Identity();
  std::string tf_error;
  const auto tfMatches = [&] {
    try {
      const auto map_odom = P->tf_buffer->lookupTransform("map", "odom", ros::Time(0));
      const auto odom_base =
          P->tf_buffer->lookupTransform("odom", "base_link", latest.header.stamp);
      err = expected.inverse() * fromTransformMsg(map_odom.transform) *
            fromTransformMsg(odom_base.transform);
      tf_error.clear();
    } catch (const std::exception& e) {
      tf_error = e.what();
      return false;
    }
    return err.translation().norm() < 1e-4;
  };
  waitFor(tfMatches, 10.0);
  ASSERT_TRUE(tf_error.empty()) << "TF map -> odom -> base_link at the latest keyframe: "
                                << tf_error;
  const double et = err.translation().norm();
  const double er = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
  std::cout << "[slam_pipeline] TF map->odom->base_link vs latest slam pose: " << et * 1000
            << " mm, " << er << " deg\n";
  // Both sides come from the same doubles: only message rounding remains.
  EXPECT_LT(et, 1e-4);
  EXPECT_LT(er, 1e-3);
  EXPECT_TRUE(P->tf_buffer->canTransform("map", "odom", ros::Time(0)));
  EXPECT_TRUE(P->tf_buffer->canTransform("base_link", "velo_link", ros::Time(0)));
}

/// map.yaml + map.pgm, read as map_server reads them, hold the grid slam/grid_map published last
/// (save_map publishes the grid it saves), cell by cell.
void expectSavedGridIsThePublishedOne(const std::string& yaml) {
  Inbox& in = P->inbox;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(5.0);
  nav_msgs::OccupancyGrid::ConstPtr published;
  test::MapServerMap saved;
  do {  // the latched message of the save may still be on its way
    ros::WallDuration(0.1).sleep();
    published = in.locked([&] { return in.grid_map; });
    saved = test::readMapServerMap(yaml);
    ASSERT_TRUE(saved.error.empty()) << saved.error;
  } while ((!published || int(published->info.width) != saved.width) &&
           ros::WallTime::now() < deadline);
  ASSERT_TRUE(published) << "nothing on slam/grid_map";
  EXPECT_EQ(published->header.frame_id, "map");
  ASSERT_EQ(int(published->info.width), saved.width);
  ASSERT_EQ(int(published->info.height), saved.height);
  EXPECT_NEAR(published->info.origin.position.x, saved.origin_x, 1e-6);
  EXPECT_NEAR(published->info.origin.position.y, saved.origin_y, 1e-6);
  size_t mismatched = 0, occupied = 0, free = 0;
  for (size_t i = 0; i < published->data.size(); ++i) {
    const int8_t v = published->data[i];
    const int8_t expected = v >= 65 ? 100 : (v >= 0 && v <= 19) ? 0 : -1;
    mismatched += saved.cells[i] != expected;
    occupied += expected == 100;
    free += expected == 0;
  }
  std::cout << "[slam_pipeline] grid " << saved.width << " x " << saved.height << ": " << occupied
            << " occupied, " << free << " free cells, "
            << in.locked([&] { return in.grid_messages; }) << " messages\n";
  EXPECT_EQ(mismatched, 0u);
  EXPECT_GT(occupied, 500u) << "the street's walls";
  EXPECT_GT(free, 5000u) << "the street";
}

TEST_F(SlamPipeline, SaveMapWritesFilesThatParse) {
  ASSERT_TRUE(P->drive_done) << "the drive did not complete (see SlamPipeline.Drive)";
  Inbox& in = P->inbox;
  const size_t n_kf = in.locked([&] { return in.keyframes.size(); });
  const fs::path out = P->dir / "map";
  SaveMap srv;
  srv.request.destination = out.string();
  srv.request.resolution = 0.5;
  ASSERT_TRUE(ros::service::call(saveMapService(), srv));
  ASSERT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_EQ(srv.response.files.size(), 10u);  // with the map package, graph/ and map.pgm
  for (const auto& f : srv.response.files) EXPECT_TRUE(fs::exists(f)) << f;
  expectSavedGridIsThePublishedOne((out / "map.yaml").string());

  pcl::PointCloud<pcl::PointXYZI> map;
  ASSERT_EQ(pcl::io::loadPCDFile((out / "map.pcd").string(), map), 0);
  EXPECT_GT(map.size(), 10000u);

  const BuildingFileResult geo =
      readBuildingsGeoJson((out / "buildings_corrected.geojson").string());
  ASSERT_TRUE(geo.ok) << geo.error;
  const OsmData osm = readOsmFile((out / "buildings_corrected.osm").string());
  ASSERT_TRUE(osm.ok) << osm.error;
  EXPECT_GE(geo.buildings.size(), 5u);
  EXPECT_EQ(osm.buildings.size(), geo.buildings.size());

  const TrajectoryReadResult tum = readTrajectory((out / "trajectory_tum.txt").string());
  ASSERT_TRUE(tum.ok) << tum.error;
  const TrajectoryReadResult kitti = readTrajectory((out / "trajectory_kitti.txt").string());
  ASSERT_TRUE(kitti.ok) << kitti.error;
  EXPECT_EQ(tum.trajectory.size(), n_kf) << "one pose per keyframe";
  EXPECT_EQ(kitti.trajectory.size(), n_kf);

  PoseGraph graph;
  const G2oReadResult g2o = readG2o((out / "graph.g2o").string(), &graph);
  ASSERT_TRUE(g2o.ok) << g2o.message;
  // Keyframes plus the buildings that got an SE2 vertex (observed ones; the GeoJSON also holds
  // the received but unobserved buildings).
  EXPECT_GT(size_t(g2o.num_vertices), n_kf) << "no building vertex in the graph";
  EXPECT_GT(size_t(g2o.num_edges), n_kf - 1) << "odometry edges only";

  // Accuracy against the simulator's truth, in the map frame itself (no alignment: the OSM
  // global matching must have found the initial heading and kept the drive on the map).
  TrajectoryEvalOptions opt;
  opt.alignment = TrajectoryAlignment::kNone;
  const TrajectoryErrors abs = evaluateTrajectory(tum.trajectory, P->ground_truth, opt);
  opt.alignment = TrajectoryAlignment::kUmeyamaSE3;
  const TrajectoryErrors aligned = evaluateTrajectory(tum.trajectory, P->ground_truth, opt);
  std::cout << "[slam_pipeline] save_map: " << map.size() << " map points, " << geo.buildings.size()
            << " buildings, " << g2o.num_vertices << " vertices, " << g2o.num_edges
            << " edges; ATE (map frame) mean " << abs.ate.mean << " m, rmse " << abs.ate.rmse
            << " m, max " << abs.ate.max << " m; ATE after SE3 alignment mean " << aligned.ate.mean
            << " m; RPE " << abs.rpe_trans.mean << " m over " << abs.associated << " keyframes\n";
  EXPECT_EQ(abs.associated, n_kf);
  EXPECT_LT(abs.ate.mean, kMaxAte);
  EXPECT_LT(abs.ate.max, 2.0 * kMaxAte);
  EXPECT_LT(aligned.ate.mean, 1.0);
}

TEST_F(SlamPipeline, DumpGraphAndUnwritableFolder) {
  ASSERT_TRUE(P->drive_done) << "the drive did not complete (see SlamPipeline.Drive)";
  DumpGraph dump;
  dump.request.destination = (P->dir / "dump").string();
  ASSERT_TRUE(ros::service::call("/graph_backend/dump_graph", dump));
  EXPECT_TRUE(dump.response.success) << dump.response.message;
  EXPECT_GT(dump.response.files.size(), P->inbox.locked([&] { return P->inbox.keyframes.size(); }))
      << "a cloud per keyframe plus the graph files";
  for (const auto& f : dump.response.files) EXPECT_TRUE(fs::exists(f)) << f;

  // A folder below a regular file cannot be created (whoever runs the test, even root).
  const fs::path blocker = P->dir / "not_a_folder";
  std::ofstream(blocker) << "x";
  SaveMap srv;
  srv.request.destination = (blocker / "map").string();
  srv.request.resolution = 0.5;
  ASSERT_TRUE(ros::service::call(saveMapService(), srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_FALSE(srv.response.message.empty());
  std::cout << "[slam_pipeline] save_map into an unwritable folder: " << srv.response.message
            << "\n";
  // Still alive afterwards.
  EXPECT_TRUE(ros::service::exists(saveMapService(), false));
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "slam_pipeline_test");
  ros::NodeHandle nh;  // keep the node alive for the whole run
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  return result;
}
