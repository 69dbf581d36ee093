#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>

#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "test_data.h"

using namespace osm_graph_slam;

namespace {

/// A drive of n poses along a gentle S-curve, 1 m apart, 10 Hz.
Trajectory makeDrive(size_t n) {
  Trajectory t;
  double x = 0, y = 0, yaw = 0;
  for (size_t i = 0; i < n; ++i) {
    StampedPose sp;
    sp.stamp = 0.1 * static_cast<double>(i);
    sp.pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    sp.pose.translation() = Eigen::Vector3d(x, y, 0.01 * static_cast<double>(i % 7));
    t.push_back(sp);
    yaw += 0.02 * std::sin(0.01 * static_cast<double>(i));
    x += std::cos(yaw);
    y += std::sin(yaw);
  }
  return t;
}

}  // namespace

TEST(TrajectoryEval, ConstantOffsetGivesExactAteAndZeroRpe) {
  const Trajectory gt = makeDrive(300);
  Trajectory est = gt;
  for (auto& sp : est) sp.pose.translation() += Eigen::Vector3d(0.6, -0.8, 0.0);  // |d| = 1
  const TrajectoryErrors e = evaluateTrajectory(est, gt);
  EXPECT_EQ(e.associated, 300u);
  EXPECT_NEAR(e.ate.mean, 1.0, 1e-9);
  EXPECT_NEAR(e.ate.std, 0.0, 1e-6);
  EXPECT_NEAR(e.ate.rmse, 1.0, 1e-9);
  EXPECT_NEAR(e.rpe_trans.mean, 0.0, 1e-9);
  EXPECT_NEAR(e.rpe_rot.mean, 0.0, 1e-9);

  TrajectoryEvalOptions aligned;
  aligned.alignment = TrajectoryAlignment::kUmeyamaSE3;
  EXPECT_LT(evaluateTrajectory(est, gt, aligned).ate.max, 1e-9);
  aligned.alignment = TrajectoryAlignment::kFirstPose;
  EXPECT_LT(evaluateTrajectory(est, gt, aligned).ate.max, 1e-9);
}

TEST(TrajectoryEval, RpeMatchesInjectedStepError) {
  // Every step of the estimate is 2 cm longer along the heading: t_RPE = 0.02 for each pair.
  const Trajectory gt = makeDrive(200);
  Trajectory est = gt;
  Eigen::Isometry3d acc = gt.front().pose;
  for (size_t i = 1; i < gt.size(); ++i) {
    Eigen::Isometry3d step = gt[i - 1].pose.inverse() * gt[i].pose;
    step.translation() += 0.02 * step.translation().normalized();
    acc = acc * step;
    est[i].pose = acc;
  }
  const TrajectoryErrors e = evaluateTrajectory(est, gt);
  EXPECT_NEAR(e.rpe_trans.mean, 0.02, 1e-9);
  EXPECT_NEAR(e.rpe_trans.std, 0.0, 1e-6);
  EXPECT_NEAR(e.rpe_rot.mean, 0.0, 1e-9);
  EXPECT_GT(e.ate.max, 1.0);  // drift accumulates
  // On a curve the end-point error is 2 % of the chord, which is shorter than the segment.
  EXPECT_GT(e.kitti_trans_percent, 1.5);
  EXPECT_LT(e.kitti_trans_percent, 2.0);
}

TEST(TrajectoryEval, KittiDriftOnStraightDriveIsExact) {
  Trajectory gt, est;
  for (int i = 0; i < 1000; ++i) {
    StampedPose sp;
    sp.stamp = 0.1 * i;
    sp.pose.translation() = Eigen::Vector3d(i, 0, 0);
    gt.push_back(sp);
    sp.pose.translation() = Eigen::Vector3d(1.01 * i, 0, 0);  // 1 % scale drift
    est.push_back(sp);
  }
  const TrajectoryErrors e = evaluateTrajectory(est, gt);
  EXPECT_NEAR(e.kitti_trans_percent, 1.0, 1e-9);
  EXPECT_NEAR(e.kitti_rot_deg_per_100m, 0.0, 1e-9);
  // Segments of 100..800 m starting every 10 frames within 1000 m: sum over lengths of
  // ceil((1000 - len) / 10) first frames.
  size_t expected = 0;
  for (int len = 100; len <= 800; len += 100) expected += static_cast<size_t>((999 - len) / 10 + 1);
  EXPECT_EQ(e.kitti_segments, expected);
}

TEST(TrajectoryEval, AssociationSkipsUnmatchedStamps) {
  const Trajectory gt = makeDrive(50);
  Trajectory est;
  for (size_t i = 0; i < gt.size(); i += 5) {
    StampedPose sp = gt[i];
    sp.stamp += 0.004;  // within tolerance
    est.push_back(sp);
  }
  StampedPose late = gt.back();
  late.stamp += 10.0;  // no ground truth here
  est.push_back(late);
  const auto pairs = associateByStamp(est, gt, 0.02);
  ASSERT_EQ(pairs.size(), 10u);
  EXPECT_EQ(pairs[3].second, 15u);
  EXPECT_EQ(evaluateTrajectory(est, gt).associated, 10u);
}

TEST(TrajectoryIo, KittiAndTumRoundTrip) {
  const Trajectory t = makeDrive(20);
  const std::string kitti = ::testing::TempDir() + "/traj_kitti.txt";
  const std::string tum = ::testing::TempDir() + "/traj_tum.txt";
  ASSERT_TRUE(writeKittiPoses(kitti, t, true));
  ASSERT_TRUE(writeTumTrajectory(tum, t));
  for (const std::string& path : {kitti, tum}) {
    const TrajectoryReadResult r = readTrajectory(path);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.trajectory.size(), t.size());
    for (size_t i = 0; i < t.size(); ++i) {
      EXPECT_NEAR(r.trajectory[i].stamp, t[i].stamp, 1e-9);
      EXPECT_LT((r.trajectory[i].pose.translation() - t[i].pose.translation()).norm(), 1e-9);
      EXPECT_LT((r.trajectory[i].pose.rotation() - t[i].pose.rotation()).norm(), 1e-9);
    }
  }
  std::remove(kitti.c_str());
  std::remove(tum.c_str());
}

TEST(TrajectoryIo, InterpolatePoseIsLinearAndSlerpedAndRefusesGaps) {
  Trajectory t(3);
  t[0].stamp = 1.0;
  t[1].stamp = 2.0;
  t[1].pose.translation() << 2.0, 4.0, 0.0;
  t[1].pose.linear() = Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t[2].stamp = 12.0;  // 10 s after the previous pose
  Eigen::Isometry3d p;
  ASSERT_TRUE(interpolatePose(t, 1.25, 5.0, p));
  EXPECT_NEAR((p.translation() - Eigen::Vector3d(0.5, 1.0, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(p.linear()).angle(), 0.2, 1e-12);
  EXPECT_FALSE(interpolatePose(t, 5.0, 5.0, p)) << "between poses 10 s apart";
  EXPECT_TRUE(interpolatePose(t, 5.0, 10.5, p));
  EXPECT_FALSE(interpolatePose(t, 0.0, 0.5, p)) << "1 s before the first pose";
  ASSERT_TRUE(interpolatePose(t, 12.2, 0.5, p));
  EXPECT_NEAR(p.translation().norm(), 0.0, 1e-12) << "clamped to the last pose";
  EXPECT_FALSE(interpolatePose({}, 1.0, 5.0, p));
}

TEST(TrajectoryIo, MalformedLineNamesFileAndLine) {
  const std::string path = ::testing::TempDir() + "/bad_traj.txt";
  std::ofstream(path) << "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 zero 1\n";
  const TrajectoryReadResult r = readTrajectory(path);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find(":2:"), std::string::npos) << r.error;
  EXPECT_FALSE(readKittiPoses("/nonexistent.txt").ok);
  std::remove(path.c_str());
}

TEST(TrajectoryEval, RealKittiGroundTruthAgainstNoisyCopy) {
  const std::string path = test::sharedDataPath("kitti00/poses_00_with_time.txt");
  OGS_REQUIRE_SHARED_FILE(path);
  const TrajectoryReadResult gt = readKittiPoses(path);
  ASSERT_TRUE(gt.ok) << gt.error;
  ASSERT_EQ(gt.trajectory.size(), 4541u);  // KITTI 00 has 4541 frames
  EXPECT_NEAR(evaluateTrajectory(gt.trajectory, gt.trajectory).ate.max, 0.0, 1e-12);
  // Gaussian position noise of sigma 0.1 m per axis (3D): mean |d| = sigma * 2 sqrt(2/pi).
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.1);
  Trajectory est = gt.trajectory;
  for (auto& sp : est) sp.pose.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  const TrajectoryErrors e = evaluateTrajectory(est, gt.trajectory);
  EXPECT_NEAR(e.ate.mean, 0.1 * 2.0 * std::sqrt(2.0 / M_PI), 0.004);
  EXPECT_NEAR(e.ate.rmse, 0.1 * std::sqrt(3.0), 0.004);
  EXPECT_GT(e.kitti_segments, 1000u);
}

TEST(TrajectoryEval, HeightDriftIgnoresTheStartOffsetAndTiltIgnoresYaw) {
  const Trajectory gt = makeDrive(101);
  Trajectory est = gt;
  for (size_t i = 0; i < est.size(); ++i) {
    // 2 m altitude error at the origin (GNSS), 1 cm of height drift per pose, a 0.5 deg roll
    // error, and a 3 deg yaw error that must not count as tilt.
    est[i].pose.translation().z() += 2.0 + 0.01 * double(i);
    est[i].pose.linear() = Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()) * gt[i].pose.linear() *
                           Eigen::AngleAxisd(0.5 * M_PI / 180.0, Eigen::Vector3d::UnitX());
  }
  const TrajectoryErrors e = evaluateTrajectory(est, gt);
  EXPECT_NEAR(e.height_drift.max, 1.0, 1e-9);
  EXPECT_NEAR(e.height_drift.mean, 0.5, 1e-9);
  EXPECT_NEAR(e.tilt.mean, 0.5 * M_PI / 180.0, 1e-9);
  EXPECT_NEAR(e.tilt.max, 0.5 * M_PI / 180.0, 1e-9);
}
