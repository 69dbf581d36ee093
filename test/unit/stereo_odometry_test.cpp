// Stereo features and visual odometry (visual/): calibration, triangulation, disparities of a
// synthetic pair, and the odometry on the real KITTI stereo sequence against its ground truth.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/visual/stereo_odometry.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

StereoCamera kittiCamera() {
  StereoCamera c;
  c.fx = c.fy = 707.0912;
  c.cx = 601.8873;
  c.cy = 183.1104;
  c.baseline = 0.537;
  return c;
}

TEST(StereoCamera, ReadsKittiCalibrationWithAndWithoutKeys) {
  const fs::path dir = fs::temp_directory_path() / "ogs_stereo_calib";
  fs::create_directories(dir);
  const std::string p0 = "707.0912 0 601.8873 0 0 707.0912 183.1104 0 0 0 1 0";
  const std::string p1 = "707.0912 0 601.8873 -379.8145 0 707.0912 183.1104 0 0 0 1 0";
  std::ofstream(dir / "keyed.txt") << "P0: " << p0 << "\nP1: " << p1 << "\nP2: " << p0 << "\n";
  std::ofstream(dir / "plain.txt") << p0 << "\n" << p1 << "\n";
  std::ofstream(dir / "short.txt") << "P0: 707 0 601\nP1: " << p1 << "\n";
  for (const char* name : {"keyed.txt", "plain.txt"}) {
    std::string error;
    const auto c = readKittiStereoCalibration((dir / name).string(), &error);
    ASSERT_TRUE(c.has_value()) << name << ": " << error;
    EXPECT_DOUBLE_EQ(c->fx, 707.0912);
    EXPECT_DOUBLE_EQ(c->cy, 183.1104);
    EXPECT_NEAR(c->baseline, 0.537150, 1e-6);
  }
  std::string error;
  EXPECT_FALSE(readKittiStereoCalibration((dir / "short.txt").string(), &error).has_value());
  EXPECT_NE(error.find("fewer than 12"), std::string::npos) << error;
  EXPECT_FALSE(readKittiStereoCalibration((dir / "none.txt").string(), &error).has_value());
  fs::remove_all(dir);
}

TEST(StereoCamera, TriangulationInvertsProjection) {
  const StereoCamera c = kittiCamera();
  const Eigen::Vector3d p(2.0, -1.0, 15.0);
  const Eigen::Vector2d uv = c.project(p);
  const double disparity = c.fx * c.baseline / p.z();
  EXPECT_LT((c.triangulate(uv.x(), uv.y(), disparity) - p).norm(), 1e-9);
}

/// A textured image (blurred noise: corners everywhere) and its view from a camera `baseline`
/// to the right when the scene is a wall facing the pair at depth fx b / disparity.
void syntheticPair(int disparity, cv::Mat& left, cv::Mat& right) {
  cv::Mat noise(370, 1226 + disparity, CV_8U);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(noise, noise, cv::Size(5, 5), 1.2);
  left = noise(cv::Rect(0, 0, 1226, 370)).clone();
  right = noise(cv::Rect(disparity, 0, 1226, 370)).clone();  // the wall `disparity` px left
}

TEST(StereoFeatures, AWallAtKnownDepthGivesItsDisparity) {
  const StereoCamera c = kittiCamera();
  cv::Mat left, right;
  syntheticPair(20, left, right);
  const StereoFrame f = extractStereoFrame(left, right, c, StereoFeatureParams());
  ASSERT_GT(f.stereoMatches(), 500u);
  size_t right_disparity = 0;
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    if (!f.has_depth[i]) continue;
    right_disparity += std::abs(f.disparity[i] - 20.0f) < 0.5f;
    EXPECT_NEAR(f.points[i].z(), c.fx * c.baseline / f.disparity[i], 1e-6);
  }
  // Noise has no repetition: nearly every match is the true one (measured 1,068 of 1,098).
  EXPECT_GT(right_disparity, f.stereoMatches() * 95 / 100);
}

// The real KITTI odometry stereo sequence (51 pairs, 59.9 m, ground truth): every pair tracked,
// the end within 2 % of the path and 2 deg of the truth.
TEST(StereoOdometry, TracksTheRealKittiSequence) {
  const fs::path dir = test::sharedDataPath("kitti_stereo/sequence_1");
  if (!fs::exists(dir / "calib.txt")) GTEST_SKIP() << dir << " not found";
  std::string error;
  const auto camera = readKittiStereoCalibration((dir / "calib.txt").string(), &error);
  ASSERT_TRUE(camera.has_value()) << error;
  const TrajectoryReadResult truth = readKittiPoses((dir / "poses.txt").string());
  ASSERT_TRUE(truth.ok) << truth.error;
  StereoOdometry odometry(*camera, StereoOdometryParams());
  std::vector<Eigen::Isometry3d> poses;
  for (size_t i = 0; i < truth.trajectory.size(); ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%06zu.png", i);
    const cv::Mat left = cv::imread((dir / "image_l" / name).string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat right = cv::imread((dir / "image_r" / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(left.empty() || right.empty()) << name;
    poses.push_back(odometry.track(left, right).pose);
  }
  EXPECT_EQ(odometry.lost(), 0u);
  double path = 0.0, worst_step = 0.0;
  for (size_t i = 1; i < poses.size(); ++i) {
    const Eigen::Isometry3d& a = truth.trajectory[i - 1].pose;
    const Eigen::Isometry3d& b = truth.trajectory[i].pose;
    path += (b.translation() - a.translation()).norm();
    const Eigen::Isometry3d step =
        (a.inverse() * b).inverse() * (poses[i - 1].inverse() * poses[i]);
    worst_step = std::max(worst_step, step.translation().norm());
  }
  const Eigen::Isometry3d end = truth.trajectory.back().pose.inverse() * poses.back();
  const double drift = end.translation().norm() / path;
  const double rotation = Eigen::AngleAxisd(end.linear()).angle() * 180.0 / M_PI;
  std::cout << "[stereo_odometry] " << poses.size() << " pairs, " << path << " m: end drift "
            << 100.0 * drift << " %, " << rotation << " deg; worst pair " << worst_step << " m\n";
  EXPECT_LT(drift, 0.02);      // measured 0.88 %
  EXPECT_LT(rotation, 2.0);    // measured 0.95 deg
  EXPECT_LT(worst_step, 0.2);  // measured 0.056 m; an aliased pair was 12 m off
}

}  // namespace
}  // namespace osm_graph_slam
