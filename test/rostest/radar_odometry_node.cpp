// Rostest node for radar_odometry.test: simulates a MulRan-layout radar drive (sim/radar_sim.h),
// publishes its sweeps as radar/polar images (mono8, frame radar_polar, as mulran2bag writes
// them) into the RadarOdometryNodelet of launch/radar.launch in lock-step (each image waits for
// its radar/status), with an empty, a wrong-size, a wrong-encoding and an out-of-order image in
// between and a 30 s gap at the end. Checks radar/odom against the simulator's truth (travel
// and end point within 5 %), radar/path, radar/features, the TF, the status counters, and that
// the second nodelet (namespace bad, an unknown detector) refused to start.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/sim/radar_sim.h"
#include "radar_rostest_utils.h"

namespace osm_graph_slam {
namespace {

using radar_rostest::toImage;
using radar_rostest::value;
using radar_rostest::waitFor;

constexpr size_t kSweeps = 48;  // 12 s of driving before the gap
constexpr size_t kFirst = 20;   // the first simulated sweep (the car is under way)
const ros::Time kStart(1000.0);

struct Received {
  std::mutex mutex;
  std::vector<nav_msgs::Odometry> odom;
  std::vector<diagnostic_msgs::DiagnosticArray> status;
  nav_msgs::Path path;
  sensor_msgs::PointCloud2 features;
  int feature_clouds = 0;
};

class RadarOdometryRostest : public radar_rostest::RadarImageFixture<Received> {
 protected:
  void SetUp() override {
    setUpStream(60.0, 10, 100);
    path_sub_ =
        nh_.subscribe<nav_msgs::Path>("radar/path", 5, [this](const nav_msgs::PathConstPtr& m) {
          std::lock_guard<std::mutex> lock(rx_.mutex);
          rx_.path = *m;
        });
    features_sub_ = nh_.subscribe<sensor_msgs::PointCloud2>(
        "radar/features", 5, [this](const sensor_msgs::PointCloud2ConstPtr& m) {
          std::lock_guard<std::mutex> lock(rx_.mutex);
          rx_.features = *m;
          ++rx_.feature_clouds;
        });
  }

  ros::Subscriber path_sub_, features_sub_;
};

TEST_F(RadarOdometryRostest, FollowsTheSimulatedDriveThroughBadInput) {
  // The drive: the radar simulator on a small city (as radar_sim_test).
  sim::SimulationParams sp;
  sp.seed = 5;
  sp.route.length = 200.0;
  sp.city.blocks_x = sp.city.blocks_y = 4;
  sim::UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(sp, &error)) << error;
  const sim::NavtechModel model;
  const sim::RadarSimulator radar(world, model, 5);
  ASSERT_GE(radar.numScans(), kFirst + kSweeps + 4);
  auto stampOf = [&](size_t k) { return kStart + ros::Duration(radar.sweepStart(kFirst + k)); };

  ASSERT_TRUE(waitFor([&] { return image_pub_.getNumSubscribers() > 0; }, 60.0))
      << "the radar_odometry nodelet did not subscribe to radar/polar";
  ASSERT_TRUE(waitFor([&] { return features_sub_.getNumPublishers() > 0; }, 10.0));
  ASSERT_TRUE(statusConnected()) << "radar/status is not connected";

  const size_t half = kSweeps / 2;
  for (size_t k = 0; k < kSweeps; ++k) {
    const radar::RadarPolarScan scan = radar.simulate(kFirst + k);
    const diagnostic_msgs::DiagnosticArray s = send(toImage(scan, stampOf(k)));
    EXPECT_EQ(value(s, "event"), "processed") << "sweep " << k << ": " << s.status[0].message;
    if (k != half - 1) continue;
    // Bad input in the middle of the drive: each is dropped, counted, and the stream goes on.
    sensor_msgs::Image empty;
    empty.header.stamp = stampOf(k) + ros::Duration(0.1);
    empty.header.frame_id = "radar_polar";
    empty.encoding = "mono8";
    sensor_msgs::Image narrow = toImage(scan, empty.header.stamp);
    narrow.width = narrow.step = 1000;
    narrow.data.resize(size_t(narrow.height) * narrow.width);
    sensor_msgs::Image colour = toImage(scan, empty.header.stamp);
    colour.encoding = "rgb8";
    const sensor_msgs::Image old = toImage(radar.simulate(kFirst + 3), stampOf(3));
    const diagnostic_msgs::DiagnosticArray se = send(empty);
    EXPECT_EQ(value(se, "event"), "bad_image");
    EXPECT_NE(se.status[0].message.find("empty image"), std::string::npos) << se.status[0].message;
    const diagnostic_msgs::DiagnosticArray sn = send(narrow);
    EXPECT_EQ(value(sn, "event"), "bad_image");
    EXPECT_NE(sn.status[0].message.find("wrong size 1000 x 400"), std::string::npos)
        << sn.status[0].message;
    EXPECT_EQ(sn.status[0].level, diagnostic_msgs::DiagnosticStatus::WARN);
    const diagnostic_msgs::DiagnosticArray sc = send(colour);
    EXPECT_EQ(value(sc, "event"), "bad_image");
    const diagnostic_msgs::DiagnosticArray so = send(old);
    EXPECT_EQ(value(so, "event"), "out_of_order");
    EXPECT_EQ(value(so, "bad_images"), "3");
    EXPECT_EQ(value(so, "out_of_order"), "1");
  }
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(rx_.mutex);
        return rx_.odom.size() >= kSweeps && rx_.path.poses.size() >= kSweeps;
      },
      10.0));

  // Odometry against the truth: the radar poses at the sweeps' mid times, in the first one's
  // frame (the odometry's frame).
  std::vector<nav_msgs::Odometry> odom;
  {
    std::lock_guard<std::mutex> lock(rx_.mutex);
    odom = rx_.odom;
  }
  ASSERT_EQ(odom.size(), kSweeps);
  const double mid = 0.5 * model.rotation_period * (model.azimuths - 1) / model.azimuths;
  auto truthAt = [&](size_t k) { return radar.radarPose(radar.sweepStart(kFirst + k) + mid); };
  const Eigen::Isometry3d first_inverse = truthAt(0).inverse();
  double est_travel = 0, true_travel = 0, worst_step = 0;
  for (size_t k = 0; k < kSweeps; ++k) {
    EXPECT_EQ(odom[k].header.frame_id, "radar_odom");
    EXPECT_EQ(odom[k].child_frame_id, "radar_polar");
    EXPECT_NEAR(odom[k].header.stamp.toSec(), (stampOf(k) + ros::Duration(mid)).toSec(), 1e-6);
    if (k == 0) continue;
    const Eigen::Vector2d e0 = fromPoseMsg(odom[k - 1].pose.pose).translation().head<2>();
    const Eigen::Vector2d e1 = fromPoseMsg(odom[k].pose.pose).translation().head<2>();
    const Eigen::Vector2d g0 = (first_inverse * truthAt(k - 1)).translation().head<2>();
    const Eigen::Vector2d g1 = (first_inverse * truthAt(k)).translation().head<2>();
    est_travel += (e1 - e0).norm();
    true_travel += (g1 - g0).norm();
    worst_step = std::max(worst_step, std::abs((e1 - e0).norm() - (g1 - g0).norm()));
  }
  const Eigen::Vector2d est_end = fromPoseMsg(odom.back().pose.pose).translation().head<2>();
  const Eigen::Vector2d true_end = (first_inverse * truthAt(kSweeps - 1)).translation().head<2>();
  const double end_error = (est_end - true_end).norm();
  std::printf(
      "[radar_odometry] %zu sweeps: estimated travel %.3f m, true %.3f m (%.2f %%); end point "
      "error %.3f m (%.2f %% of the travel); worst step-length error %.3f m\n",
      kSweeps, est_travel, true_travel, 100.0 * (est_travel - true_travel) / true_travel, end_error,
      100.0 * end_error / true_travel, worst_step);
  EXPECT_GT(true_travel, 40.0);
  EXPECT_NEAR(est_travel, true_travel, 0.05 * true_travel);
  EXPECT_LT(end_error, 0.05 * true_travel);
  // The velocity in the twist: the truth's speed at the last sweep.
  const double true_speed =
      radar.radarVelocity(radar.sweepStart(kFirst + kSweeps - 1) + mid).head<2>().norm();
  EXPECT_NEAR(odom.back().twist.twist.linear.x, true_speed, 0.1 * true_speed + 0.2);

  // Path, features, TF and the final counters.
  {
    std::lock_guard<std::mutex> lock(rx_.mutex);
    EXPECT_EQ(rx_.path.header.frame_id, "radar_odom");
    EXPECT_EQ(rx_.path.poses.size(), kSweeps);
    EXPECT_GT(rx_.feature_clouds, 0);
    EXPECT_EQ(rx_.features.header.frame_id, "radar_polar");
    std::vector<std::string> names;
    for (const auto& f : rx_.features.fields) names.push_back(f.name);
    EXPECT_EQ(names, (std::vector<std::string>{"x", "y", "z", "power"}));
    EXPECT_GT(rx_.features.width * rx_.features.height, 100u);
    const diagnostic_msgs::DiagnosticArray& last = rx_.status.back();
    EXPECT_EQ(value(last, "received"), std::to_string(kSweeps + 4));
    EXPECT_EQ(value(last, "processed"), std::to_string(kSweeps));
    EXPECT_EQ(value(last, "bad_images"), "3");
    EXPECT_EQ(value(last, "out_of_order"), "1");
    EXPECT_EQ(value(last, "gaps"), "0");
    EXPECT_EQ(value(last, "ransac_failures"), "0");
    EXPECT_GT(std::stoi(value(last, "inliers")), 8);
    EXPECT_GT(std::stod(value(last, "ms_per_scan")), 0.0);
  }
  std::string tf_error;
  EXPECT_TRUE(tf_buffer_->canTransform("radar_odom", "radar_polar", odom.back().header.stamp,
                                       ros::Duration(5.0), &tf_error))
      << tf_error;

  // A 30 s gap: the odometry restarts with zero velocity at the same pose, then moves on.
  const ros::Duration gap(30.0);
  const Eigen::Isometry3d before_gap = fromPoseMsg(odom.back().pose.pose);
  const diagnostic_msgs::DiagnosticArray g0 =
      send(toImage(radar.simulate(kFirst + kSweeps), stampOf(kSweeps) + gap));
  EXPECT_EQ(value(g0, "event"), "restarted");
  EXPECT_EQ(value(g0, "gaps"), "1");
  for (size_t k = kSweeps + 1; k < kSweeps + 4; ++k) {
    const diagnostic_msgs::DiagnosticArray s =
        send(toImage(radar.simulate(kFirst + k), stampOf(k) + gap));
    EXPECT_EQ(value(s, "event"), "processed");
  }
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(rx_.mutex);
        return rx_.odom.size() >= kSweeps + 4;
      },
      10.0));
  {
    std::lock_guard<std::mutex> lock(rx_.mutex);
    const nav_msgs::Odometry& restart = rx_.odom[kSweeps];
    EXPECT_EQ(restart.twist.twist.linear.x, 0.0);
    EXPECT_TRUE(fromPoseMsg(restart.pose.pose).isApprox(before_gap, 1e-9));
    const double after_speed = rx_.odom.back().twist.twist.linear.x;
    EXPECT_NEAR(after_speed, true_speed, 0.2 * true_speed + 0.5);
  }

  // The nodelet with a bad parameter (namespace bad) logged the reason and did not start: no
  // subscription, no publication, and the shared manager is alive (the good one answered above).
  ros::master::V_TopicInfo topics;
  ASSERT_TRUE(ros::master::getTopics(topics));
  for (const auto& t : topics) EXPECT_NE(t.name.rfind("/bad/radar", 0), 0u) << t.name;
  ros::Publisher bad_pub = nh_.advertise<sensor_msgs::Image>("/bad/radar/polar", 1);
  ros::WallDuration(1.0).sleep();
  EXPECT_EQ(bad_pub.getNumSubscribers(), 0u);
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "radar_odometry_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
