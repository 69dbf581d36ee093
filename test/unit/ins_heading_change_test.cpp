// INS heading changes as evidence: with ins_heading_std > 0 each keyframe's INS heading change
// since the keyframe ins_heading_span back is a robust yaw-difference edge, so the heading drifts
// with the INS's noise instead of the odometry's (doc/matrix.md: 9.5 deg after 1.5 km from a
// LiDAR's intrinsic calibration error), and the INS's constant bias cancels.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "backend_test_utils.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/slam/graph_backend.h"

using namespace osm_graph_slam;

namespace {

constexpr double kDeg = M_PI / 180.0;

struct HeadingErrors {
  double final_yaw_deg = 0.0;  ///< |yaw| of the last keyframe (the truth is 0)
  double max_lateral = 0.0;    ///< max |y| (the truth is 0)
};

/// 200 keyframes 2 m apart along x with heading 0; the odometry turns 0.02 deg too much per step
/// (a 4 deg drift at the end). The INS says 0.3 deg (its bias) plus 0.1 deg noise, one keyframe
/// 20 deg (an outlier).
HeadingErrors drive(double ins_heading_std, bool heading_known) {
  GraphBackendParams params = noOsmKnownHeading();
  params.initial_yaw_known = heading_known;
  params.gnss.ins_heading_std = ins_heading_std;
  GraphBackend backend(params);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.translation().x() = 2.0;
  step.linear() = Eigen::AngleAxisd(0.02 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (uint64_t i = 0; i < 200; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.odom_pose = odom;  // turning a little too much
    kf.ins_yaw = (i == 120 ? 20.0 : 0.3 + noise(rng)) * kDeg;
    backend.addKeyframe(kf);
    odom = odom * step;
  }
  backend.update(true);
  HeadingErrors e;
  const Trajectory t = backend.trajectory();
  for (const auto& p : t)
    e.max_lateral = std::max(e.max_lateral, std::abs(p.pose.translation().y()));
  e.final_yaw_deg = std::abs(planarPose(t.back().pose).theta) / kDeg;
  return e;
}

}  // namespace

TEST(InsHeadingChange, BoundsTheOdometrysHeadingDriftAndTheBiasCancels) {
  const HeadingErrors off = drive(0.0, true), on = drive(0.002, true);
  std::printf(
      "[ins_heading] final heading error: off %.2f deg, INS changes %.2f deg; max lateral"
      " %.2f -> %.2f m\n",
      off.final_yaw_deg, on.final_yaw_deg, off.max_lateral, on.max_lateral);
  EXPECT_NEAR(off.final_yaw_deg, 199 * 0.02, 0.05);  // the odometry's drift, nothing corrects it
  // Not the INS's 0.3 deg bias: only its changes count; the 20 deg outlier is down-weighted.
  EXPECT_LT(on.final_yaw_deg, 0.5);
  EXPECT_LT(on.max_lateral, off.max_lateral / 5.0);
}

TEST(InsHeadingChange, WorksWithoutAKnownInitialHeading) {
  // The INS's yaw frame may differ from the map's by a constant: it cancels as the bias does.
  const HeadingErrors e = drive(0.002, false);
  EXPECT_LT(e.final_yaw_deg, 0.5);
}
