// Rostest node for frontend.test: writes a bag from the six real patchwork scans (plus one
// all-NaN scan) with the rosbag C++ API, plays it into the running nodelets in lock-step, and
// checks odom, keyframe, status and TF against the direct registration of scans 0 -> 5.
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <mutex>
#include <vector>

#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/ScanMatchingStatus.h"
#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/registration/registration.h"
#include "osm_graph_slam/ros/conversions.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

constexpr int kScans = 6;

std::string patchworkScan(int i) {
  char name[64];
  std::snprintf(name, sizeof(name), "patchwork/%06d.bin", i);
  return test::sharedDataPath(name);
}

/// The mounting used in the test: velodyne 0.27 m ahead of and 1.73 m above base_link.
Eigen::Isometry3d sensorToBase() {
  return fromXyzRpy(0.27, 0.0, 1.73, 0.0, 0.0, 0.0);
}

struct Received {
  std::mutex mutex;
  std::vector<nav_msgs::Odometry> odom;
  std::vector<KeyFrame> keyframes;
  std::vector<ScanMatchingStatus> status;
  int filtered = 0;
};

bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.02).sleep();
  }
  return done();
}

/// Writes the bag: scans 0..5 at 10 Hz from `start`, an all-NaN scan between scans 2 and 3.
void writeBag(const std::string& path, const ros::Time& start) {
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  for (int i = 0; i < kScans; ++i) {
    PointCloud cloud;
    ASSERT_TRUE(readKittiBin(patchworkScan(i), cloud));
    sensor_msgs::PointCloud2 msg;
    toPointCloud2(cloud, msg);
    msg.header.frame_id = "velodyne";
    msg.header.stamp = start + ros::Duration(0.1 * i);
    bag.write("/velodyne_points", msg.header.stamp, msg);
    if (i == 2) {
      PointCloud nan_cloud;
      PointT p;
      p.x = p.y = p.z = std::numeric_limits<float>::quiet_NaN();
      for (int k = 0; k < 500; ++k) nan_cloud.push_back(p);
      toPointCloud2(nan_cloud, msg);
      msg.header.frame_id = "velodyne";
      msg.header.stamp = start + ros::Duration(0.1 * i + 0.05);
      bag.write("/velodyne_points", msg.header.stamp, msg);
    }
  }
  bag.close();
}

/// Scan 0 -> 5 motion of base_link by direct registration (coarse 5 m pass, then defaults).
Eigen::Isometry3d directRegistration() {
  CloudPrefilterParams params;
  params.sensor_to_base = sensorToBase();
  CloudPrefilter prefilter(params);
  PointCloud raw0, raw5;
  readKittiBin(patchworkScan(0), raw0);
  readKittiBin(patchworkScan(kScans - 1), raw5);
  const auto target = prefilter.filter(raw0).cloud;
  const auto source = prefilter.filter(raw5).cloud;
  RegistrationParams coarse;
  coarse.max_correspondence_distance = 5.0;
  auto reg = createRegistration(coarse);
  reg->setTarget(target);
  const auto rough = reg->align(source, Eigen::Isometry3d::Identity());
  auto fine = createRegistration(RegistrationParams());
  fine->setTarget(target);
  const auto result = fine->align(source, rough.transform);
  EXPECT_TRUE(result.converged) << result.message;
  return result.transform;
}

TEST(FrontendRostest, ReplayedBagGivesOdometryKeyframesAndTf) {
  OGS_REQUIRE_SHARED_FILE(patchworkScan(kScans - 1));
  ros::NodeHandle nh;
  Received rx;
  auto odom_sub =
      nh.subscribe<nav_msgs::Odometry>("odom", 20, [&](const nav_msgs::OdometryConstPtr& m) {
        std::lock_guard<std::mutex> lock(rx.mutex);
        rx.odom.push_back(*m);
      });
  auto kf_sub = nh.subscribe<KeyFrame>("keyframe", 20, [&](const KeyFrameConstPtr& m) {
    std::lock_guard<std::mutex> lock(rx.mutex);
    rx.keyframes.push_back(*m);
  });
  auto status_sub = nh.subscribe<ScanMatchingStatus>("scan_matching_status", 20,
                                                     [&](const ScanMatchingStatusConstPtr& m) {
                                                       std::lock_guard<std::mutex> lock(rx.mutex);
                                                       rx.status.push_back(*m);
                                                     });
  auto filtered_sub = nh.subscribe<sensor_msgs::PointCloud2>(
      "filtered_points", 20, [&](const sensor_msgs::PointCloud2ConstPtr& m) {
        std::lock_guard<std::mutex> lock(rx.mutex);
        ++rx.filtered;
        EXPECT_EQ(m->header.frame_id, "base_link");
      });
  tf2_ros::Buffer tf_buffer;
  tf2_ros::TransformListener tf_listener(tf_buffer);
  tf2_ros::StaticTransformBroadcaster static_tf;
  geometry_msgs::TransformStamped mount;
  mount.header.stamp = ros::Time::now();
  mount.header.frame_id = "base_link";
  mount.child_frame_id = "velodyne";
  mount.transform = toTransformMsg(sensorToBase());
  static_tf.sendTransform(mount);
  ros::AsyncSpinner spinner(2);
  spinner.start();

  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("ogs_frontend_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string bag_path = (dir / "patchwork.bag").string();
  writeBag(bag_path, ros::Time::now());

  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("velodyne_points", 10);
  // Every topic we count must be connected before the first scan: a subscriber that links up
  // late misses the first message (a loaded CI machine lost the first filtered cloud).
  ASSERT_TRUE(waitFor(
      [&] {
        return pub.getNumSubscribers() > 0 && odom_sub.getNumPublishers() > 0 &&
               kf_sub.getNumPublishers() > 0 && status_sub.getNumPublishers() > 0 &&
               filtered_sub.getNumPublishers() > 0;
      },
      60.0))
      << "the front-end nodelets did not come up";
  auto count = [&](auto member) {
    std::lock_guard<std::mutex> lock(rx.mutex);
    return member();
  };
  // Lock-step replay: the next scan only after the previous one produced its odometry.
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  int valid_sent = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    const auto msg = m.instantiate<sensor_msgs::PointCloud2>();
    ASSERT_TRUE(msg);
    const bool nan_scan = msg->width == 500;
    const int filtered_before = count([&] { return rx.filtered; });
    pub.publish(msg);
    if (nan_scan) {
      ros::WallDuration(2.0).sleep();
      EXPECT_EQ(count([&] { return rx.filtered; }), filtered_before)
          << "an all-NaN scan must publish nothing";
      continue;
    }
    ++valid_sent;
    ASSERT_TRUE(
        waitFor([&] { return count([&] { return int(rx.odom.size()); }) >= valid_sent; }, 120.0))
        << "no odometry for scan " << valid_sent - 1;
  }
  bag.close();
  std::filesystem::remove_all(dir);
  // Status, filtered clouds and keyframes are topics of their own: the last may arrive after its
  // odometry (a fixed 0.5 s wait lost one on a loaded CI machine). Wait for them, bounded.
  waitFor(
      [&] {
        return count([&] {
          return rx.filtered >= kScans && rx.status.size() >= size_t(kScans) &&
                 rx.keyframes.size() >= 2;
        });
      },
      30.0);
  ros::WallDuration(0.5).sleep();  // anything beyond kScans would show up in the counts below

  std::lock_guard<std::mutex> lock(rx.mutex);
  EXPECT_EQ(rx.filtered, kScans);
  ASSERT_EQ(rx.odom.size(), size_t(kScans));
  ASSERT_EQ(rx.status.size(), size_t(kScans));
  for (const auto& s : rx.status) {
    EXPECT_FALSE(s.failed) << s.message;
    // Tracking health travels with every status: a healthy replay reports ok and no failure.
    EXPECT_EQ(s.tracking_state, "ok");
    EXPECT_EQ(s.failed_matches, 0u);
    EXPECT_EQ(s.lost_events, 0u);
    EXPECT_LT(s.time_since_keyframe, 0.35);  // keyframes at scans 0 and 3, 10 Hz
  }
  for (const auto& k : rx.keyframes) EXPECT_FALSE(k.tracking_recovered);
  // 0.74 m per scan and a new keyframe every 2 m: keyframes at scans 0 and 3.
  ASSERT_EQ(rx.keyframes.size(), 2u);
  EXPECT_EQ(rx.keyframes[0].id, 0u);
  EXPECT_EQ(rx.keyframes[1].id, 1u);
  EXPECT_EQ(rx.keyframes[1].header.stamp, rx.odom[3].header.stamp);
  EXPECT_GT(rx.keyframes[1].cloud.width, 1000u);
  EXPECT_NEAR(rx.keyframes[1].accum_distance, 2.2, 0.3);
  const auto& last = rx.odom.back();
  EXPECT_EQ(last.header.frame_id, "odom");
  EXPECT_EQ(last.child_frame_id, "base_link");
  const Eigen::Isometry3d final_pose = fromPoseMsg(last.pose.pose);

  const auto tf =
      tf_buffer.lookupTransform("odom", "base_link", last.header.stamp, ros::Duration(2.0));
  const Eigen::Isometry3d tf_pose = fromTransformMsg(tf.transform);
  EXPECT_LT((tf_pose.inverse() * final_pose).translation().norm(), 1e-6);

  const Eigen::Isometry3d direct = directRegistration();
  const Eigen::Isometry3d err = direct.inverse() * final_pose;
  const double et = err.translation().norm();
  const double er = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
  std::cout << "[frontend rostest] final |t| = " << final_pose.translation().norm()
            << " m; vs direct registration " << et * 100 << " cm, " << er << " deg\n";
  EXPECT_GT(final_pose.translation().norm(), 3.0);
  EXPECT_LT(et, 0.05);
  EXPECT_LT(er, 0.2);
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "frontend_test");
  ros::NodeHandle nh;  // keep the node alive for the whole run
  return RUN_ALL_TESTS();
}
