// INS heading as evidence: with ins_heading_std > 0 every keyframe's INS yaw is a robust heading
// prior, so the heading is bounded by the INS's error instead of drifting with the odometry's
// (doc/matrix.md: 9.5 deg after 1.5 km from a LiDAR's intrinsic calibration error).
#include <gtest/gtest.h>

#include <cmath>

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
/// (a 4 deg drift at the end). The INS says 0.3 deg (its bias), one keyframe 20 deg (an outlier).
HeadingErrors drive(double ins_heading_std, bool heading_known) {
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = heading_known;
  params.initial_yaw = 0.0;
  params.ins_heading_std = ins_heading_std;
  GraphBackend backend(params);
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.translation().x() = 2.0;
  step.linear() = Eigen::AngleAxisd(0.02 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (uint64_t i = 0; i < 200; ++i) {
    KeyframeInput kf;
    kf.id = i;
    kf.stamp = 1.0 + i;
    kf.odom_pose = odom;
    kf.accum_distance = 2.0 * i;
    kf.odom_fitness = 0.05;
    kf.ins_yaw = (i == 120 ? 20.0 : 0.3) * kDeg;
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

TEST(InsHeadingPrior, BoundsTheOdometrysHeadingDriftAtTheInsBias) {
  const HeadingErrors off = drive(0.0, true), on = drive(0.005, true);
  std::printf(
      "[ins_heading] final heading error: off %.2f deg, priors %.2f deg; max lateral %.2f"
      " -> %.2f m\n",
      off.final_yaw_deg, on.final_yaw_deg, off.max_lateral, on.max_lateral);
  EXPECT_NEAR(off.final_yaw_deg, 199 * 0.02, 0.05);  // the odometry's drift, nothing corrects it
  EXPECT_LT(on.final_yaw_deg, 0.7);  // the INS's 0.3 deg bias, the 20 deg outlier down-weighted
  EXPECT_LT(on.max_lateral, off.max_lateral / 3.0);
}

TEST(InsHeadingPrior, UnusedWithoutAKnownInitialHeading) {
  // The INS's yaw is then not known to be the map's (global matching sets the heading later).
  const HeadingErrors e = drive(0.005, false);
  EXPECT_NEAR(e.final_yaw_deg, 199 * 0.02, 0.05);
}
