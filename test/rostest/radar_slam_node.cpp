// Rostest node for radar_slam.test: simulates a radar drive that comes back to its start (seed 1,
// a 3 x 3 block city with 45-60 m blocks, as radar_slam_test's LoopsCloseOnARouteBackToItsStart),
// publishes every sweep as a radar/polar image into the RadarOdometryNodelet of
// launch/radar.launch (loop/enabled from config/radar.yaml) in lock-step (each image waits for
// its radar/status), with the simulator's true radar position as gps/fix (10 Hz) and its true
// yaw rate as imu/data (100 Hz) up to half a second ahead of each sweep, then checks: loops
// accepted in radar/status, radar/loops (one LINE_LIST in radar_map), radar/slam_path (one
// corrected pose per sweep in radar_map), the TF radar_map -> radar_odom (not identity, and
// radar/slam_path's last pose = TF * radar/odom's last pose), that the corrected end pose is
// closer to the simulator's truth than the odometry's, the GNSS and gyro counters (anchored,
// GNSS and yaw edges, the invalid messages counted, the data before the first sweep handed
// over), and that the corrected path is no worse than RadarSlam's without GNSS and gyro (a
// RadarOdometryStream in this process with the nodelet's parameters, on the same sweeps).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/radar/radar_stream.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/ros_param_reader.h"
#include "osm_graph_slam/sim/radar_sim.h"
#include "radar_rostest_utils.h"

namespace osm_graph_slam {
namespace {

using radar_rostest::toImage;
using radar_rostest::toImu;
using radar_rostest::toNavSatFix;
using radar_rostest::value;
using radar_rostest::waitFor;

const ros::Time kStart(1000.0);
constexpr double kFixSigma = 0.5;  // [m] the fixes' covariance (their position is the truth)
constexpr double kNavAhead = 0.5;  // [s] navigation published this far past a sweep's start

/// gps/fix at 10 Hz and imu/data at 100 Hz from the simulator's truth over [0, end] s, in stamp
/// order, with three messages the nodelet must count and not use: a fix with STATUS_NO_FIX, one
/// with a NaN latitude, an Imu without rates.
struct Navigation {
  std::vector<sensor_msgs::NavSatFix> fixes;
  std::vector<sensor_msgs::Imu> imu;
};

Navigation navigationFromTruth(const sim::UrbanSimulator& world, const sim::RadarSimulator& radar,
                               double end) {
  Navigation nav;
  for (int j = 0; j * 0.1 <= end; ++j) {
    const double t = j * 0.1;
    const Eigen::Vector3d geo = world.enu().toGeodetic(radar.radarPose(t).translation());
    nav.fixes.push_back(
        toNavSatFix(geo.x(), geo.y(), geo.z(), kFixSigma, kStart + ros::Duration(t)));
    if (j == 100 || j == 200) {  // between two fixes: invalid ones
      sensor_msgs::NavSatFix bad = nav.fixes.back();
      bad.header.stamp += ros::Duration(0.05);
      if (j == 100)
        bad.status.status = sensor_msgs::NavSatStatus::STATUS_NO_FIX;
      else
        bad.latitude = std::numeric_limits<double>::quiet_NaN();
      nav.fixes.push_back(bad);
    }
  }
  // The body rate from the true attitude (central difference, one-sided at the ends).
  const double h = 1e-3;
  for (int j = 0; j * 0.01 <= end; ++j) {
    const double t = j * 0.01, t0 = std::max(0.0, t - h), t1 = t + h;
    const Eigen::AngleAxisd turn(radar.radarPose(t0).linear().transpose() *
                                 radar.radarPose(t1).linear());
    const Eigen::Vector3d rate = turn.axis() * turn.angle() / (t1 - t0);
    nav.imu.push_back(toImu(rate, kStart + ros::Duration(t)));
    if (j == 1500) nav.imu.push_back(toImu(rate, kStart + ros::Duration(t + 0.005), false));
  }
  return nav;
}

/// Planar position error of a path against the truth (both in the first sweep's frame): RMS and
/// end as they are, and the RMS after the rigid motion that fits the path best onto the truth
/// (ATE). The map frame is the first keyframe's; with GNSS the fixes turn the whole graph about
/// it (the anchor's yaw is a compromise with the odometry's heading), which the ATE leaves out.
struct PathError {
  double rms = 0.0, end = 0.0, ate = 0.0;
};

PathError pathError(const std::vector<Eigen::Vector2d>& estimate,
                    const std::vector<Eigen::Vector2d>& truth) {
  PathError e;
  const size_t n = std::min(estimate.size(), truth.size());
  if (n == 0) return e;
  Eigen::Vector2d ce = Eigen::Vector2d::Zero(), ct = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < n; ++k) {
    e.rms += (estimate[k] - truth[k]).squaredNorm();
    ce += estimate[k];
    ct += truth[k];
  }
  e.rms = std::sqrt(e.rms / double(n));
  e.end = (estimate[n - 1] - truth[n - 1]).norm();
  ce /= double(n);
  ct /= double(n);
  double dot = 0.0, cross = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d a = estimate[k] - ce, b = truth[k] - ct;
    dot += a.dot(b);
    cross += a.x() * b.y() - a.y() * b.x();
  }
  const Eigen::Rotation2Dd R(std::atan2(cross, dot));
  for (size_t k = 0; k < n; ++k) e.ate += (R * (estimate[k] - ce) + ct - truth[k]).squaredNorm();
  e.ate = std::sqrt(e.ate / double(n));
  return e;
}

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
    setUpNavigation(5000);
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

  const Navigation nav = navigationFromTruth(
      world, radar, std::min(world.trajectory().duration(), radar.sweepStart(n - 1) + kNavAhead));

  // Without GNSS and gyro: RadarSlam with the nodelet's parameters, on the same sweeps.
  const RosParamReader reader(ros::NodeHandle("/radar_odometry"));
  radar::RadarSlamParams slam_params;
  radar::RadarStreamParams stream_params;
  ASSERT_TRUE(radar::readSlamParams(reader, slam_params, &error) &&
              radar::readParams(reader, stream_params, &error))
      << error;
  radar::RadarOdometryStream reference(slam_params, stream_params);
  ASSERT_TRUE(reference.loopsEnabled());

  ASSERT_TRUE(waitFor([&] { return image_pub_.getNumSubscribers() > 0; }, 60.0))
      << "the radar_odometry nodelet did not subscribe to radar/polar";
  ASSERT_TRUE(waitFor([&] { return path_sub_.getNumPublishers() > 0; }, 10.0))
      << "no radar/slam_path publisher: loop/enabled off?";
  ASSERT_TRUE(waitFor(
      [&] { return gps_pub_.getNumSubscribers() > 0 && imu_pub_.getNumSubscribers() > 0; }, 10.0))
      << "the nodelet did not subscribe to gps/fix and imu/data: gnss/imu enabled?";
  ASSERT_TRUE(statusConnected()) << "radar/status is not connected";

  const auto wall0 = std::chrono::steady_clock::now();
  size_t next_fix = 0, next_imu = 0;
  for (size_t k = 0; k < n; ++k) {
    // The navigation up to half a second past the sweep's start first (before the first sweep:
    // held by the stream for it), as rosbag play delivers a bag in stamp order.
    const ros::Time start = kStart + ros::Duration(radar.sweepStart(k));
    const ros::Time until = start + ros::Duration(kNavAhead);
    for (; next_fix < nav.fixes.size() && nav.fixes[next_fix].header.stamp <= until; ++next_fix)
      gps_pub_.publish(nav.fixes[next_fix]);
    for (; next_imu < nav.imu.size() && nav.imu[next_imu].header.stamp <= until; ++next_imu)
      imu_pub_.publish(nav.imu[next_imu]);
    const radar::RadarPolarScan scan = radar.simulate(k);
    const diagnostic_msgs::DiagnosticArray s = send(toImage(scan, start), [&] {
      radar::PolarImageView view;
      view.data = scan.power.data();
      view.size = scan.power.size();
      view.rows = scan.num_azimuths;
      view.cols = scan.num_bins;
      view.step = size_t(scan.num_bins);
      EXPECT_TRUE(reference.process(view, int64_t(start.toNSec())).has_step) << "sweep " << k;
    });
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

  // GNSS and gyro: every message arrived and was counted, the data published before the first
  // sweep was held for it, the bad messages were counted and not used, the anchor is set, and
  // the graph has GNSS and yaw-change edges.
  auto count = [&](const std::string& key) {
    const std::string v = value(last, key);
    EXPECT_FALSE(v.empty()) << "no '" << key << "' in radar/status";
    return v.empty() ? -1L : std::stol(v);
  };
  // ROS orders messages per topic only: the last few small messages may still be queued when
  // the last sweep's status goes out (seen: 2 of 4210 rates under load). The counts must agree
  // with each other exactly.
  const long gnss_received = count("gnss_received"), imu_received = count("imu_received");
  EXPECT_LE(gnss_received, long(nav.fixes.size()));
  EXPECT_GE(gnss_received, long(nav.fixes.size()) - 5);
  EXPECT_EQ(count("gnss_invalid"), 2);
  EXPECT_EQ(count("gnss_unknown_sigma"), 0);
  EXPECT_EQ(count("gnss_fixes"), gnss_received - 2);
  EXPECT_EQ(count("gnss_rejected_sigma"), 0);
  EXPECT_EQ(count("gnss_out_of_order"), 0);
  EXPECT_GT(count("gnss_edges"), 0);
  EXPECT_EQ(value(last, "gnss_anchored"), "true");
  EXPECT_LE(imu_received, long(nav.imu.size()));
  EXPECT_GE(imu_received, long(nav.imu.size()) - 50);  // 0.5 s of 100 Hz
  EXPECT_EQ(count("imu_invalid"), 1);
  EXPECT_EQ(count("imu_samples"), imu_received - 1);
  EXPECT_EQ(count("imu_out_of_order"), 0);
  EXPECT_GT(count("imu_edges"), 0);
  EXPECT_EQ(count("imu_missing"), 0);
  EXPECT_GT(count("nav_buffered"), 0);  // what was published before the first sweep
  EXPECT_EQ(count("nav_dropped_early"), 0);

  // The corrected path against the truth, with and without GNSS and gyro.
  std::vector<Eigen::Vector2d> truth, with_nav, without_nav, odometry;
  const std::vector<Eigen::Isometry2d> reference_poses = reference.slam().sweepPoses();
  ASSERT_EQ(reference_poses.size(), n);
  for (size_t k = 0; k < n; ++k) {
    truth.push_back((first_inverse * truthAt(k)).translation().head<2>());
    with_nav.push_back(fromPoseMsg(slam_path.poses[k].pose).translation().head<2>());
    without_nav.push_back(reference_poses[k].translation());
    odometry.push_back(fromPoseMsg(odom[k].pose.pose).translation().head<2>());
  }
  const PathError e_nav = pathError(with_nav, truth), e_plain = pathError(without_nav, truth),
                  e_odom = pathError(odometry, truth);
  const radar::RadarLoopStats& rl = reference.slam().loopStats();
  std::printf(
      "[radar_slam] GNSS and gyro: %ld fixes (%ld invalid), %ld GNSS edges, %ld yaw rates (%ld "
      "invalid), %ld yaw edges, %ld missing, %ld held for the first sweep, %ld optimisations; "
      "path error ATE / rms / end: odometry %.3f / %.3f / %.3f m, without GNSS and gyro %.3f / "
      "%.3f / %.3f m (%d loops), with %.3f / %.3f / %.3f m (%d loops)\n",
      count("gnss_fixes"), count("gnss_invalid"), count("gnss_edges"), count("imu_samples"),
      count("imu_invalid"), count("imu_edges"), count("imu_missing"), count("nav_buffered"),
      count("optimisations"), e_odom.ate, e_odom.rms, e_odom.end, e_plain.ate, e_plain.rms,
      e_plain.end, rl.accepted, e_nav.ate, e_nav.rms, e_nav.end, accepted);
  EXPECT_LE(e_nav.ate, e_plain.ate);
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
