// Rostest node for radar_slam.test: simulates a radar drive that comes back to its start (seed 1,
// a 3 x 3 block city with 45-60 m blocks, as radar_slam_test's LoopsCloseOnARouteBackToItsStart),
// publishes every sweep as a radar/polar image into the RadarOdometryNodelet of
// launch/radar.launch (loop/enabled from config/radar.yaml) in lock-step (each image waits for
// its radar/status), then checks: loops accepted in radar/status, radar/loops (one LINE_LIST in
// radar_map), radar/slam_path (one corrected pose per sweep in radar_map), the TF radar_map ->
// radar_odom (not identity, and radar/slam_path's last pose = TF * radar/odom's last pose), and
// that the corrected end pose is closer to the simulator's truth than the odometry's.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
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

const ros::Time kStart(1000.0);

struct Received {
  std::mutex mutex;
  std::vector<nav_msgs::Odometry> odom;
  std::vector<diagnostic_msgs::DiagnosticArray> status;
  nav_msgs::Path slam_path;
  int slam_paths = 0;
  visualization_msgs::MarkerArray loops;
  int loop_arrays = 0;
};

double yawOf(const Eigen::Isometry3d& T) {
  return std::atan2(T.linear()(1, 0), T.linear()(0, 0));
}

class RadarSlamRostest : public radar_rostest::RadarImageFixture<Received> {
 protected:
  void SetUp() override {
    setUpStream(600.0, 4, 400);
    path_sub_ = nh_.subscribe<nav_msgs::Path>("radar/slam_path", 5,
                                              [this](const nav_msgs::PathConstPtr& m) {
                                                std::lock_guard<std::mutex> lock(rx_.mutex);
                                                rx_.slam_path = *m;
                                                ++rx_.slam_paths;
                                              });
    loops_sub_ = nh_.subscribe<visualization_msgs::MarkerArray>(
        "radar/loops", 5, [this](const visualization_msgs::MarkerArrayConstPtr& m) {
          std::lock_guard<std::mutex> lock(rx_.mutex);
          rx_.loops = *m;
          ++rx_.loop_arrays;
        });
  }

  ros::Subscriber path_sub_, loops_sub_;
};

TEST_F(RadarSlamRostest, ClosesTheLoopOfADriveBackToItsStart) {
  sim::SimulationParams sp;
  sp.seed = 1;
  sp.route.length = 200.0;
  sp.city.blocks_x = sp.city.blocks_y = 3;
  sp.city.block_min = 45.0;
  sp.city.block_max = 60.0;
  sim::UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(sp, &error)) << error;
  const sim::NavtechModel model;
  const sim::RadarSimulator radar(world, model, 1);
  const size_t n = radar.numScans();
  ASSERT_GT(n, 100u);

  ASSERT_TRUE(waitFor([&] { return image_pub_.getNumSubscribers() > 0; }, 60.0))
      << "the radar_odometry nodelet did not subscribe to radar/polar";
  ASSERT_TRUE(waitFor([&] { return path_sub_.getNumPublishers() > 0; }, 10.0))
      << "no radar/slam_path publisher: loop/enabled off?";

  const auto wall0 = std::chrono::steady_clock::now();
  for (size_t k = 0; k < n; ++k) {
    const diagnostic_msgs::DiagnosticArray s =
        send(toImage(radar.simulate(k), kStart + ros::Duration(radar.sweepStart(k))));
    ASSERT_EQ(value(s, "event"), "processed") << "sweep " << k;
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(rx_.mutex);
        return rx_.odom.size() >= n && rx_.slam_path.poses.size() >= n;
      },
      10.0));

  std::vector<nav_msgs::Odometry> odom;
  nav_msgs::Path slam_path;
  diagnostic_msgs::DiagnosticArray last;
  visualization_msgs::MarkerArray loops;
  int loop_arrays = 0;
  {
    std::lock_guard<std::mutex> lock(rx_.mutex);
    odom = rx_.odom;
    slam_path = rx_.slam_path;
    last = rx_.status.back();
    loops = rx_.loops;
    loop_arrays = rx_.loop_arrays;
  }
  ASSERT_EQ(odom.size(), n);

  // Loop counters.
  const int accepted = std::stoi(value(last, "loops_accepted"));
  const int candidates = std::stoi(value(last, "loop_candidates"));
  const int rejected_registration = std::stoi(value(last, "loops_rejected_registration"));
  const int rejected_gate = std::stoi(value(last, "loops_rejected_gate"));
  const double ms_per_keyframe = std::stod(value(last, "loop_ms_per_keyframe"));
  EXPECT_GE(accepted, 1);
  EXPECT_GE(candidates, accepted + rejected_registration + rejected_gate);
  EXPECT_GT(ms_per_keyframe, 0.0);
  EXPECT_GT(std::stoi(value(last, "keyframes")), 20);

  // radar/loops: one LINE_LIST with one segment per accepted loop, rebuilt on each loop.
  EXPECT_EQ(loop_arrays, accepted);
  ASSERT_EQ(loops.markers.size(), 1u);
  const visualization_msgs::Marker& m = loops.markers[0];
  EXPECT_EQ(m.header.frame_id, "radar_map");
  EXPECT_EQ(m.type, visualization_msgs::Marker::LINE_LIST);
  EXPECT_EQ(m.points.size(), 2u * size_t(accepted));

  // radar/slam_path: one pose per sweep, in radar_map, stamped as radar/odom.
  EXPECT_EQ(slam_path.header.frame_id, "radar_map");
  ASSERT_EQ(slam_path.poses.size(), n);
  for (size_t k = 0; k < n; ++k)
    EXPECT_EQ(slam_path.poses[k].header.stamp, odom[k].header.stamp) << k;

  // The TF radar_map -> radar_odom at the last sweep: not identity, and it maps the odometry's
  // last pose onto the corrected one.
  geometry_msgs::TransformStamped map_to_odom;
  try {
    map_to_odom = tf_buffer_->lookupTransform("radar_map", "radar_odom", odom.back().header.stamp,
                                              ros::Duration(5.0));
  } catch (const std::exception& e) {
    FAIL() << e.what();
  }
  const Eigen::Isometry3d correction = fromTransformMsg(map_to_odom.transform);
  const double correction_m = correction.translation().norm();
  const double correction_deg = std::abs(yawOf(correction)) * 180.0 / M_PI;
  EXPECT_GT(correction_m + correction_deg, 1e-3) << "the correction is identity";
  const Eigen::Isometry3d odom_end = fromPoseMsg(odom.back().pose.pose);
  const Eigen::Isometry3d slam_end = fromPoseMsg(slam_path.poses.back().pose);
  EXPECT_TRUE((correction * odom_end).isApprox(slam_end, 1e-6));
  std::string tf_error;
  EXPECT_TRUE(tf_buffer_->canTransform("radar_map", "radar_polar", odom.back().header.stamp,
                                       ros::Duration(5.0), &tf_error))
      << tf_error;

  // Against the truth: the radar pose at each sweep's mid time, in the first sweep's frame (the
  // odometry's and, with the first keyframe fixed, the map's).
  auto truthAt = [&](size_t k) { return radar.radarPose((odom[k].header.stamp - kStart).toSec()); };
  const Eigen::Isometry3d first_inverse = truthAt(0).inverse();
  const Eigen::Vector2d true_end = (first_inverse * truthAt(n - 1)).translation().head<2>();
  double travel = 0.0;
  for (size_t k = 1; k < n; ++k)
    travel += (truthAt(k).translation() - truthAt(k - 1).translation()).head<2>().norm();
  const double odom_error = (odom_end.translation().head<2>() - true_end).norm();
  const double slam_error = (slam_end.translation().head<2>() - true_end).norm();
  std::printf(
      "[radar_slam] %zu sweeps, %.1f m, %s keyframes, %.1f s wall (%.1f ms per sweep in the "
      "nodelet, %.2f ms per keyframe in the back-end); loops: %d accepted, %d candidates, %d "
      "rejected by registration, %d by the gate; correction %.3f m %.3f deg; end error: odometry "
      "%.3f m, corrected %.3f m\n",
      n, travel, value(last, "keyframes").c_str(), wall, std::stod(value(last, "ms_per_scan_mean")),
      ms_per_keyframe, accepted, candidates, rejected_registration, rejected_gate, correction_m,
      correction_deg, odom_error, slam_error);
  EXPECT_GT(odom_error, 0.3);  // else the drive is too easy to show anything
  EXPECT_LT(slam_error, 0.5 * odom_error);
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "radar_slam_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
