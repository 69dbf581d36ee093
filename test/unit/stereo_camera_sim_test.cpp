// The simulated stereo camera (sim/stereo_camera_sim.h): geometry of the rendered pair, texture a
// feature detector can use, determinism, and the stereo odometry on rendered pairs against the
// simulator's truth.
#include <gtest/gtest.h>

#include <iostream>

#include "osm_graph_slam/sim/simulator.h"
#include "osm_graph_slam/sim/stereo_camera_sim.h"
#include "osm_graph_slam/visual/stereo_odometry.h"

namespace osm_graph_slam::sim {
namespace {

const UrbanSimulator& defaultSim() {
  static UrbanSimulator sim;
  static bool built = false;
  if (!built) {
    std::string error;
    EXPECT_TRUE(sim.build(SimulationParams(), &error)) << error;
    built = true;
  }
  return sim;
}

StereoCamera cameraOf(const StereoCameraModel& m) {
  StereoCamera c;
  c.fx = m.fx;
  c.fy = m.fy;
  c.cx = m.cx;
  c.cy = m.cy;
  c.baseline = m.baseline;
  return c;
}

TEST(StereoCameraSim, PairsAreDeterministicAndTheirStereoDepthsAreTheScene) {
  const UrbanSimulator& sim = defaultSim();
  const StereoCameraModel model;
  const double t = sim.scanTime(100);
  const Eigen::Isometry3d camera = kittiCameraFromLidar(sim.sensorPose(t));
  cv::Mat left, right, again_left, again_right;
  renderStereoPair(sim.scene().world, model, camera, t, 5, left, right);
  renderStereoPair(sim.scene().world, model, camera, t, 5, again_left, again_right);
  ASSERT_EQ(left.size(), cv::Size(1226, 370));
  EXPECT_EQ(cv::norm(left, again_left, cv::NORM_L1), 0.0);
  EXPECT_EQ(cv::norm(right, again_right, cv::NORM_L1), 0.0);
  // Enough texture for FAST, and the triangulated points lie on the scene: each one's ray, cast
  // into the world, hits a surface at the triangulated depth.
  const StereoFrame f = extractStereoFrame(left, right, cameraOf(model), StereoFeatureParams());
  ASSERT_GT(f.stereoMatches(), 300u);
  size_t on_scene = 0, checked = 0;
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    if (!f.has_depth[i] || f.points[i].z() > 30.0) continue;
    const Eigen::Vector3d ray = (camera.linear() * f.points[i]).normalized();
    RayHit hit;
    if (!sim.scene().world.castRay(camera.translation(), ray, 200.0, t, hit)) continue;
    ++checked;
    on_scene += std::abs(hit.range - f.points[i].norm()) < 0.1 * f.points[i].norm();
  }
  std::cout << "[stereo_camera_sim] " << f.stereoMatches() << " stereo points, " << on_scene
            << " of " << checked << " within 10 % of the scene's depth\n";
  // The rest lie on silhouettes (a corner mixes a near edge with the far background) or on the
  // facades' repeated windows (measured 214 of 274).
  ASSERT_GT(checked, 100u);
  EXPECT_GT(on_scene, checked * 70 / 100);
}

TEST(StereoCameraSim, StereoOdometryFollowsTheSimulatedDrive) {
  const UrbanSimulator& sim = defaultSim();
  const StereoCameraModel model;
  StereoOdometry odometry(cameraOf(model), StereoOdometryParams());
  const Eigen::Isometry3d first = kittiCameraFromLidar(sim.sensorPose(0.0));
  constexpr size_t kPairs = 20;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  double path = 0.0;
  Eigen::Isometry3d previous_truth = Eigen::Isometry3d::Identity();
  for (size_t i = 0; i < kPairs; ++i) {
    const double t = sim.scanTime(i);
    const Eigen::Isometry3d camera = kittiCameraFromLidar(sim.sensorPose(t));
    cv::Mat left, right;
    renderStereoPair(sim.scene().world, model, camera, t, 5, left, right);
    pose = odometry.track(left, right).pose;
    const Eigen::Isometry3d truth = first.inverse() * camera;
    path += (truth.translation() - previous_truth.translation()).norm();
    previous_truth = truth;
  }
  const Eigen::Isometry3d end = previous_truth.inverse() * pose;
  std::cout << "[stereo_camera_sim] " << kPairs << " rendered pairs, " << path << " m: end error "
            << end.translation().norm() << " m, "
            << Eigen::AngleAxisd(end.linear()).angle() * 180.0 / M_PI << " deg\n";
  EXPECT_EQ(odometry.lost(), 0u);
  EXPECT_LT(end.translation().norm(), 0.03 * path);
  EXPECT_LT(Eigen::AngleAxisd(end.linear()).angle(), 2.0 * M_PI / 180.0);
}

}  // namespace
}  // namespace osm_graph_slam::sim
