// Rostest node for fault_injection.test (issue 22, point 4): the SLAM nodelets of
// launch/osm_graph_slam.launch on simulated time, fed in lock-step with 60 real KITTI raw 0005
// scans (velo_link, 10 Hz) with faults injected: a NaN-only scan, a duplicated stamp, a scan in
// a frame without TF, a 30 s gap, an empty scan, an out-of-order stamp, a GNSS fix with NaN and
// one with status NO_FIX, an IMU at 1 Hz throughout, then the time jumps back to the start and
// scans 0..29 come again (a looped bag). Each fault must give its log line on /rosout (once),
// be counted where the status counts it, and the run must go on: keyframes after every fault
// reach the back-end, and save_map at the end holds every keyframe published before.
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/SaveMap.h"
#include "osm_graph_slam/ScanMatchingStatus.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/ros/conversions.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

constexpr int kScans = 60;      // drive 0005 scans 0..59 (~25 m)
constexpr int kLoopScans = 30;  // scans 0..29 again after the jump back
constexpr const char* kSensorFrame = "velo_link";
const ros::Time kStart(1317000000, 0);  // the drive's day (2011-09-26), as a bag would have it
// Drive 0005 frame 0 (kitti_raw_0005/oxts_frame0.txt).
constexpr double kLat = 49.011212804408, kLon = 8.4228850417969, kAlt = 112.83, kYaw = -1.2219;

bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.01).sleep();
  }
  return done();
}

std::string stampText(const ros::Time& t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.3f", t.toSec());
  return buf;
}

/// Everything the nodelets publish that the test checks.
struct Inbox {
  std::mutex mutex;
  std::vector<ScanMatchingStatus> status;
  std::vector<KeyFrame> keyframes;  ///< without clouds
  std::vector<rosgraph_msgs::Log> logs;
  nav_msgs::Path path;                        ///< the back-end's latest
  std::vector<ros::Time> map_to_odom_stamps;  ///< of graph_backend's TF broadcasts
  size_t filtered = 0;

  template <typename F>
  auto locked(F f) {
    std::lock_guard<std::mutex> lock(mutex);
    return f();
  }
  size_t statusCount() {
    return locked([&] { return status.size(); });
  }
  /// Log lines (warn and above, or info) containing every one of the parts.
  size_t countLogs(const std::vector<std::string>& parts) {
    return locked([&] {
      size_t n = 0;
      for (const auto& l : logs) {
        bool all = true;
        for (const auto& p : parts) all = all && l.msg.find(p) != std::string::npos;
        n += all;
      }
      return n;
    });
  }
};

/// A saved graph.g2o: keyframe positions by id (VERTEX_SE3:QUAT) and the SE3 edges' vertex pairs.
struct SavedGraph {
  std::map<uint64_t, Eigen::Vector3d> vertices;
  std::vector<std::pair<uint64_t, uint64_t>> edges;
};

SavedGraph readG2o(const std::string& path) {
  SavedGraph g;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tag;
    uint64_t a = 0, b = 0;
    Eigen::Vector3d p;
    if (!(s >> tag >> a)) continue;
    if (tag == "VERTEX_SE3:QUAT" && s >> p.x() >> p.y() >> p.z()) g.vertices[a] = p;
    if (tag == "EDGE_SE3:QUAT" && s >> b) g.edges.emplace_back(a, b);
  }
  return g;
}

class FaultInjection : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ogs_fault_injection_" + std::to_string(::getpid()));
    status_sub_ = nh_.subscribe<ScanMatchingStatus>("scan_matching_status", 100,
                                                    [this](const ScanMatchingStatusConstPtr& m) {
                                                      in_.locked([&] { in_.status.push_back(*m); });
                                                    });
    kf_sub_ = nh_.subscribe<KeyFrame>("keyframe", 100, [this](const KeyFrameConstPtr& m) {
      KeyFrame k = *m;
      k.cloud.data.clear();
      in_.locked([&] { in_.keyframes.push_back(k); });
    });
    tf_sub_ = nh_.subscribe<tf2_msgs::TFMessage>(
        "/tf", 100, [this](const tf2_msgs::TFMessageConstPtr& m) {
          for (const auto& t : m->transforms)
            if (t.header.frame_id == "map" && t.child_frame_id == "odom")
              in_.locked([&] { in_.map_to_odom_stamps.push_back(t.header.stamp); });
        });
    path_sub_ = nh_.subscribe<nav_msgs::Path>(
        "slam/path", 10,
        [this](const nav_msgs::PathConstPtr& m) { in_.locked([&] { in_.path = *m; }); });
    filtered_sub_ = nh_.subscribe<sensor_msgs::PointCloud2>(
        "filtered_points", 100,
        [this](const sensor_msgs::PointCloud2ConstPtr&) { in_.locked([&] { ++in_.filtered; }); });
    log_sub_ = nh_.subscribe<rosgraph_msgs::Log>("/rosout", 1000,
                                                 [this](const rosgraph_msgs::LogConstPtr& m) {
                                                   if (m->name == ros::this_node::getName()) return;
                                                   in_.locked([&] { in_.logs.push_back(*m); });
                                                 });
    clock_pub_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", 10, true);
    scan_pub_ = nh_.advertise<sensor_msgs::PointCloud2>("velodyne_points", 10);
    imu_pub_ = nh_.advertise<sensor_msgs::Imu>("imu/data", 10);
    fix_pub_ = nh_.advertise<sensor_msgs::NavSatFix>("gps/fix", 10);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Sim time goes on to t; never back (a scan stamped in the past must not move the clock:
  /// tf2's listener would log a jump back in time, the test jumps back only with setClock()).
  void clock(const ros::Time& t) {
    if (t > now_) setClock(t);
  }
  void setClock(const ros::Time& t) {
    rosgraph_msgs::Clock c;
    c.clock = t;
    clock_pub_.publish(c);
    now_ = t;
  }

  sensor_msgs::PointCloud2Ptr scan(int frame, const ros::Time& stamp,
                                   const std::string& frame_id = kSensorFrame) {
    PointCloud cloud;
    EXPECT_TRUE(readKittiBin(files_[frame], cloud)) << files_[frame];
    sensor_msgs::PointCloud2Ptr msg(new sensor_msgs::PointCloud2);
    toPointCloud2(cloud, *msg);
    msg->header.frame_id = frame_id;
    msg->header.stamp = stamp;
    return msg;
  }

  sensor_msgs::PointCloud2Ptr cloudMsg(const PointCloud& cloud, const ros::Time& stamp) {
    sensor_msgs::PointCloud2Ptr msg(new sensor_msgs::PointCloud2);
    toPointCloud2(cloud, *msg);
    msg->header.frame_id = kSensorFrame;
    msg->header.stamp = stamp;
    return msg;
  }

  /// The 1 Hz IMU: a sample at every whole second of sim time up to t (from `imu_next_`).
  void imuUpTo(const ros::Time& t) {
    while (imu_next_ <= t) {
      sensor_msgs::Imu imu;
      imu.header.stamp = imu_next_;
      imu.header.frame_id = "base_link";
      const Eigen::Quaterniond q(Eigen::AngleAxisd(kYaw, Eigen::Vector3d::UnitZ()));
      imu.orientation.w = q.w();
      imu.orientation.z = q.z();
      imu.orientation_covariance[0] = 1e-4;
      imu.angular_velocity_covariance[0] = -1.0;
      imu.linear_acceleration_covariance[0] = -1.0;
      imu_pub_.publish(imu);
      imu_next_ += ros::Duration(1.0);
    }
  }

  void fix(const ros::Time& t, double lat, double lon, int8_t status) {
    sensor_msgs::NavSatFix f;
    f.header.stamp = t;
    f.header.frame_id = "gps";
    f.status.status = status;
    f.latitude = lat;
    f.longitude = lon;
    f.altitude = kAlt;
    f.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN;
    fix_pub_.publish(f);
  }

  /// Publishes a scan that reaches the tracker and waits for its status.
  void play(const sensor_msgs::PointCloud2Ptr& msg) {
    clock(msg->header.stamp);
    imuUpTo(msg->header.stamp);
    const size_t before = in_.statusCount();
    scan_pub_.publish(msg);
    ASSERT_TRUE(waitFor([&] { return in_.statusCount() > before; }, 60.0))
        << "no status for the scan at " << stampText(msg->header.stamp);
  }

  /// Publishes a scan that the prefilter drops, and waits for the log line naming it while
  /// the clock runs on in steps of 50 ms up to `run_to` (a TF lookup waits on sim time).
  void playDropped(const sensor_msgs::PointCloud2Ptr& msg, const std::vector<std::string>& line,
                   const ros::Time& run_to) {
    clock(msg->header.stamp);
    const size_t statuses = in_.statusCount();
    scan_pub_.publish(msg);
    bool logged = false;
    for (ros::Time t = msg->header.stamp; !logged; t += ros::Duration(0.05)) {
      if (t <= run_to) clock(t);
      logged = waitFor([&] { return in_.countLogs(line) > 0; }, t <= run_to ? 0.1 : 10.0);
      if (t > run_to) break;
    }
    EXPECT_TRUE(logged) << "no log line with '" << line.front() << "' for the scan at "
                        << stampText(msg->header.stamp);
    ros::WallDuration(0.3).sleep();
    EXPECT_EQ(in_.statusCount(), statuses) << "a dropped scan reached the tracker";
  }

  size_t keyframeCount() {
    return in_.locked([&] { return in_.keyframes.size(); });
  }

  ros::NodeHandle nh_;
  Inbox in_;
  fs::path dir_;
  std::vector<std::string> files_;
  ros::Subscriber status_sub_, kf_sub_, tf_sub_, path_sub_, filtered_sub_, log_sub_;
  ros::Publisher clock_pub_, scan_pub_, imu_pub_, fix_pub_;
  ros::Time now_, imu_next_;
};

TEST_F(FaultInjection, EveryFaultIsReportedOnceAndTheMapIsKept) {
  const std::string archive = test::sharedDataPath("kitti_raw_0005/velodyne.tar.xz");
  const std::string calib = test::sharedDataPath("kitti_raw_0005/calib_2011_09_26.txt");
  OGS_REQUIRE_SHARED_FILE(archive);
  OGS_REQUIRE_SHARED_FILE(calib);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  clock(kStart);
  std::string error;
  files_ = test::unpackKitti0005Scans(dir_ / "kitti_raw_0005", 0, kScans, &error);
  ASSERT_EQ(files_.size(), size_t(kScans)) << error;

  // The KITTI mounting: base_link is the OXTS unit (as kitti2bag). No TF for kGhostFrame.
  Eigen::Isometry3d velo_from_imu;
  ASSERT_TRUE(readKittiTrackingCalib(calib, "Tr_imu_to_velo", velo_from_imu, &error)) << error;
  tf2_ros::StaticTransformBroadcaster static_tf;
  geometry_msgs::TransformStamped mount;
  mount.header.stamp = kStart;
  mount.header.frame_id = "base_link";
  mount.child_frame_id = kSensorFrame;
  mount.transform = toTransformMsg(velo_from_imu.inverse());
  static_tf.sendTransform(mount);

  ros::ServiceClient save = nh_.serviceClient<SaveMap>("/graph_backend/save_map");
  ASSERT_TRUE(waitFor(
      [&] {
        return scan_pub_.getNumSubscribers() > 0 && status_sub_.getNumPublishers() > 0 &&
               kf_sub_.getNumPublishers() > 0 && fix_pub_.getNumSubscribers() > 0 &&
               imu_pub_.getNumSubscribers() > 0 && save.exists();
      },
      60.0))
      << "the nodelets did not come up: subscribers of velodyne_points "
      << scan_pub_.getNumSubscribers() << ", gps/fix " << fix_pub_.getNumSubscribers()
      << ", imu/data " << imu_pub_.getNumSubscribers() << "; publishers of the status "
      << status_sub_.getNumPublishers() << ", keyframe " << kf_sub_.getNumPublishers()
      << "; save_map " << (save.exists() ? "up" : "missing");
  ros::WallDuration(1.0).sleep();  // the static TF reaches the prefilter's listener

  const ros::Duration period(0.1);
  imu_next_ = kStart;
  fix(kStart, kLat, kLon, sensor_msgs::NavSatStatus::STATUS_FIX);  // the map origin
  ros::WallDuration(0.3).sleep();
  ros::Time t = kStart;  // stamp of the next scan
  auto normal = [&](int frame) {
    play(scan(frame, t));
    t += period;
  };
  const auto lastStatus = [&] { return in_.locked([&] { return in_.status.back(); }); };

  // Scans 0..19: the map before any fault.
  for (int i = 0; i < 20; ++i) normal(i);

  // 1. NaN-only scan (between scans 19 and 20).
  PointCloud nan_cloud;
  PointT nan_point;
  nan_point.x = nan_point.y = nan_point.z = std::numeric_limits<float>::quiet_NaN();
  for (int k = 0; k < 1000; ++k) nan_cloud.push_back(nan_point);
  const ros::Time nan_stamp = t - ros::Duration(0.05);
  playDropped(cloudMsg(nan_cloud, nan_stamp), {stampText(nan_stamp), "publishes nothing"},
              nan_stamp);
  for (int i = 20; i < 25; ++i) normal(i);

  // 2. Duplicated stamp: scan 24 again with its stamp.
  const ros::Time dup_stamp = t - period;
  play(scan(24, dup_stamp));
  {
    const ScanMatchingStatus s = lastStatus();
    EXPECT_TRUE(s.failed);
    EXPECT_EQ(s.message.rfind("rejected_stamp", 0), 0u) << s.message;
    EXPECT_EQ(s.rejected_scans, 1u);
  }
  for (int i = 25; i < 30; ++i) normal(i);

  // 3. A scan in a frame without TF (scan 30's points): dropped after the TF wait (0.2 s of sim
  //    time), then the drive goes on 0.4 s later.
  playDropped(scan(30, t, "lidar_without_tf"), {"no transform", "lidar_without_tf"},
              t + ros::Duration(0.35));
  t += ros::Duration(0.4);
  for (int i = 31; i < 35; ++i) normal(i);

  // 4. A 30 s gap before scan 35 (the recording paused).
  t += ros::Duration(30.0);
  const ros::Time gap_end = t;
  const size_t keyframes_before_gap = keyframeCount();
  for (int i = 35; i < 40; ++i) normal(i);

  // 5. Empty scan (between scans 39 and 40).
  const ros::Time empty_stamp = t - ros::Duration(0.05);
  playDropped(cloudMsg(PointCloud(), empty_stamp), {stampText(empty_stamp), "publishes nothing"},
              empty_stamp);
  for (int i = 40; i < 45; ++i) normal(i);

  // 6. Out-of-order stamp: scan 45 stamped 50 ms before scan 44.
  const ros::Time ooo_stamp = t - period - ros::Duration(0.05);
  play(scan(45, ooo_stamp));
  {
    const ScanMatchingStatus s = lastStatus();
    EXPECT_TRUE(s.failed);
    EXPECT_EQ(s.message.rfind("rejected_stamp", 0), 0u) << s.message;
    EXPECT_EQ(s.rejected_scans, 2u);
  }
  // 7. GNSS: a fix with NaN coordinates, later one with status NO_FIX.
  fix(t, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
      sensor_msgs::NavSatStatus::STATUS_FIX);
  for (int i = 45; i < 50; ++i) normal(i);
  fix(t, kLat, kLon, sensor_msgs::NavSatStatus::STATUS_NO_FIX);
  for (int i = 50; i < kScans; ++i) normal(i);
  const ros::Time first_pass_end = t - period;

  // Everything of the first pass reaches the back-end and is optimised before the jump: the map
  // (slam/path) to compare the end's with.
  ros::WallDuration(1.0).sleep();
  const std::vector<KeyFrame> first_pass = in_.locked([&] { return in_.keyframes; });
  ASSERT_FALSE(first_pass.empty());
  EXPECT_GT(first_pass.size(), keyframes_before_gap) << "no keyframe after the 30 s gap";
  ASSERT_TRUE(waitFor(
      [&] { return in_.locked([&] { return in_.path.poses.size() == first_pass.size(); }); }, 20.0))
      << "slam/path never held the first pass's " << first_pass.size() << " keyframes";
  const nav_msgs::Path map_before_jump = in_.locked([&] { return in_.path; });

  // 8. The time jumps back to the start (a looped bag): scans 0..29 again with their stamps,
  //    the IMU and the fix too.
  const size_t tf_before_jump = in_.locked([&] { return in_.map_to_odom_stamps.size(); });
  t = kStart;
  imu_next_ = kStart;
  setClock(kStart);  // the one jump back
  fix(kStart, kLat, kLon, sensor_msgs::NavSatStatus::STATUS_FIX);
  for (int i = 0; i < kLoopScans; ++i) normal(i);
  ros::WallDuration(1.0).sleep();

  // save_map holds every keyframe published, from before and after each fault.
  SaveMap srv;
  srv.request.destination = (dir_ / "map").string();
  srv.request.resolution = 0.5;
  ASSERT_TRUE(save.call(srv));
  ASSERT_TRUE(srv.response.success) << srv.response.message;
  const SavedGraph graph = readG2o((dir_ / "map" / "graph.g2o").string());
  std::set<uint64_t> saved;
  for (const auto& v : graph.vertices) saved.insert(v.first);
  ros::WallDuration(1.0).sleep();  // the last log lines

  std::lock_guard<std::mutex> lock(in_.mutex);
  std::printf(
      "[fault_injection] %zu scans reached the tracker, %zu filtered, %zu keyframes "
      "published (%zu in the first pass), %zu in the saved graph; save_map: %s\n",
      in_.status.size(), in_.filtered, in_.keyframes.size(), first_pass.size(), saved.size(),
      srv.response.message.c_str());
  for (const auto& l : in_.logs)
    if (l.level >= rosgraph_msgs::Log::WARN || l.msg.find("jumped back") != std::string::npos)
      std::printf("[fault_injection] log %d: %s\n", int(l.level), l.msg.c_str());

  const KeyFrame& restart_kf = in_.keyframes[first_pass.size()];
  std::printf(
      "[fault_injection] the first pass ended %.1f m from the start; the restart keyframe "
      "%lu (really at the start) continues there\n",
      fromPoseMsg(first_pass.back().odom_pose).translation().norm(),
      static_cast<unsigned long>(restart_kf.id));
  for (const auto& s : in_.status)
    if (s.failed || s.tracking_state != "ok")
      std::printf("[fault_injection] status at %s: %s, %s\n", stampText(s.header.stamp).c_str(),
                  s.tracking_state.c_str(), s.message.c_str());
  for (const auto& k : in_.keyframes)
    EXPECT_TRUE(saved.count(k.id)) << "keyframe " << k.id << " lost from the map";
  // The first pass's map is where it was before the jump (the second pass hangs from it by a
  // weak edge and pulls nothing).
  double moved = 0.0;
  for (size_t i = 0; i < first_pass.size(); ++i) {
    const auto v = graph.vertices.find(first_pass[i].id);
    if (v == graph.vertices.end()) continue;
    const auto& p = map_before_jump.poses[i].pose.position;
    moved = std::max(moved, (v->second - Eigen::Vector3d(p.x, p.y, p.z)).norm());
  }
  size_t loops = 0;
  for (const auto& [a, b] : graph.edges) loops += (a > b ? a - b : b - a) > 1;
  std::printf(
      "[fault_injection] first-pass keyframes moved at most %.3f m from slam/path before "
      "the jump to the saved map; %zu loop edges\n",
      moved, loops);
  // The restart keyframe is scan 0 again, really at the start. loop_detection searches every
  // keyframe after a restart (relocalize_after_restart) and its loop places the new pass there;
  // before, it hung where the first pass ended (19.8 m off).
  const auto v_start = graph.vertices.find(first_pass.front().id);
  const auto v_restart = graph.vertices.find(restart_kf.id);
  ASSERT_TRUE(v_start != graph.vertices.end() && v_restart != graph.vertices.end());
  const double restart_offset = (v_restart->second - v_start->second).norm();
  std::printf("[fault_injection] the restart keyframe is %.2f m from the first keyframe\n",
              restart_offset);
  EXPECT_LT(restart_offset, 1.0) << "the pass after the jump back was not placed by a loop";
  // map -> odom goes on at the new (earlier) times after the clock jumped back.
  const size_t tf_after_jump =
      std::count_if(in_.map_to_odom_stamps.begin() + tf_before_jump, in_.map_to_odom_stamps.end(),
                    [&](const ros::Time& t) { return t < first_pass_end - ros::Duration(5.0); });
  EXPECT_GT(tf_after_jump, 0u) << "no map -> odom at the times after the jump";
  EXPECT_LT(moved, 0.05);  // 0.004 m; 0.12 m while a floor edge tied the restart keyframe
  EXPECT_GE(saved.size(), in_.keyframes.size());
  // Keyframe ids keep increasing across the restart (the back-end orders by id).
  for (size_t i = 1; i < in_.keyframes.size(); ++i)
    EXPECT_GT(in_.keyframes[i].id, in_.keyframes[i - 1].id);

  // Statuses: every scan but the one without TF, plus the duplicated and the out-of-order one.
  const size_t expected_status = kScans - 1 + 2 + kLoopScans;
  ASSERT_EQ(in_.status.size(), expected_status);
  const ScanMatchingStatus& last = in_.status.back();
  EXPECT_EQ(last.rejected_scans, 2u);
  EXPECT_EQ(last.restarts, 1u);
  size_t restarted = 0, failed = 0;
  for (const auto& s : in_.status) {
    restarted += s.tracking_state == "restarted";
    failed += s.failed;
  }
  EXPECT_EQ(restarted, 1u);
  // Failed: the two rejected stamps and the restart; the scan after the 30 s gap may fail once
  // before the recovery's zero-motion guess matches.
  EXPECT_GE(failed, 3u);
  EXPECT_LE(failed, 6u);
  const auto restart_it = std::find_if(in_.status.begin(), in_.status.end(), [](const auto& s) {
    return s.tracking_state == "restarted";
  });
  ASSERT_NE(restart_it, in_.status.end());
  EXPECT_EQ(restart_it->header.stamp, kStart);
  EXPECT_TRUE(restart_it->new_keyframe);
  size_t keyframes_after_restart = 0;
  for (const auto& k : in_.keyframes)
    keyframes_after_restart += k.header.stamp < first_pass_end && k.id > first_pass.back().id;
  EXPECT_GE(keyframes_after_restart, 3u) << "tracking did not go on after the jump back";
  EXPECT_TRUE(in_.keyframes[first_pass.size()].tracking_recovered)
      << "the restart keyframe must be linked weakly";
  // The prefilter publishes every scan that reached the tracker, none of the three dropped.
  EXPECT_EQ(in_.filtered, expected_status);

  // One clear line per fault. Throttled lines name the scan's stamp.
  auto logs = [&](const std::vector<std::string>& parts) {
    size_t n = 0;
    for (const auto& l : in_.logs) {
      bool all = true;
      for (const auto& p : parts) all = all && l.msg.find(p) != std::string::npos;
      n += all;
    }
    return n;
  };
  EXPECT_EQ(logs({stampText(nan_stamp), "publishes nothing"}), 1u) << "NaN-only scan";
  EXPECT_EQ(logs({stampText(empty_stamp), "publishes nothing"}), 1u) << "empty scan";
  EXPECT_EQ(logs({"stamp " + stampText(dup_stamp) + " is not after"}), 1u) << "duplicated stamp";
  EXPECT_EQ(logs({"stamp " + stampText(ooo_stamp) + " is not after"}), 1u) << "out-of-order stamp";
  EXPECT_EQ(logs({"Detected jump back in time"}), 1u) << "jump back: tf2 listener";
  EXPECT_EQ(logs({"clock jumped back", "map -> odom restamped"}), 1u) << "jump back: map -> odom";
  EXPECT_EQ(logs({"no transform", "lidar_without_tf"}), 1u) << "missing TF";
  EXPECT_EQ(logs({"no scan for 30.", stampText(gap_end)}), 1u) << "30 s gap";
  EXPECT_EQ(logs({"non-finite position"}), 1u) << "NaN fix";
  EXPECT_EQ(logs({"has no fix (status -1)"}), 1u) << "NO_FIX fix";
  // Throttled (5 s of stamps): 36 s of the first pass, the loop restarts the throttle.
  const size_t slow_imu = logs({"imu/data: 1.00 s between samples"});
  EXPECT_GE(slow_imu, 1u) << "IMU at 1 Hz";
  EXPECT_LE(slow_imu, 12u) << "IMU at 1 Hz: not throttled";
  EXPECT_EQ(logs({"tracking restart 1", "time jumped back"}), 1u) << "jump back: scan matching";
  EXPECT_EQ(logs({"the time jumped back", "the map so far is kept"}), 1u) << "jump back: back-end";
  EXPECT_EQ(logs({"imu/data jumped back"}), 1u) << "jump back: IMU buffer";
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "fault_injection_test");
  ros::NodeHandle nh;  // keep the node alive for the whole run
  return RUN_ALL_TESTS();
}
