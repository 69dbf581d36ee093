// A keyframe the tracker re-anchored after a lost track is linked by a weak odometry edge: a loop
// closure can then move it across the gap, where a normal edge would hold it; the flag survives
// dump_graph and replay.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/map_export.h"

using namespace osm_graph_slam;

namespace {

/// Keyframes every 2 m along x (odometry); keyframe 3 was re-anchored 1.5 m too far (odometry
/// says x = 7.5, truth 6.0) and a loop closure from keyframe 3 to keyframe 0 says 6.0.
Matrix6d someHessian() {
  Matrix6d h = Matrix6d::Identity() * 4e5;
  h(0, 4) = h(4, 0) = -1.5e4;
  h(5, 5) = 1.25e8;
  return h;
}

struct Drive {
  bool reanchored = false;
  double hessian_weight = 0.0;
  double loop_information = 100.0;  // 10 cm, 0.1 rad
  std::string loop_kernel = GraphBackendParams().loops.loop_kernel;
  double prediction_error = 0.0005;  // [m] ahead, of keyframe 2's match (the one with a Hessian)
  double prediction_error_scale = 1.0;
};

/// The optimised keyframes' x.
std::vector<double> optimisedX(const Drive& drive, std::string* dump_dir = nullptr) {
  const bool reanchored = drive.reanchored;
  GraphBackendParams params;
  params.use_osm = false;
  params.odometry.information.hessian_weight = drive.hessian_weight;
  params.odometry.information.prediction_error_scale = drive.prediction_error_scale;
  // The steps' own information alone: an estimated scale would shorten every step for the loop.
  params.odometry.odometry_scale_window = 0.0;
  params.loops.loop_kernel = drive.loop_kernel;
  GraphBackend backend(params);
  const double xs[] = {0.0, 2.0, 4.0, 7.5};
  for (uint64_t i = 0; i < 4; ++i) {
    KeyframeInput kf;
    kf.id = i;
    kf.stamp = 1.0 + i;
    kf.odom_pose.translation().x() = xs[i];
    kf.odom_fitness = 0.05;
    kf.reanchored = reanchored && i == 3;
    if (i == 2) {
      kf.odom_hessian = someHessian();
      kf.odom_prediction_error.x() = drive.prediction_error;
    }
    backend.addKeyframe(kf);
  }
  LoopClosureInput loop;
  loop.from_id = 3;
  loop.to_id = 0;
  loop.relative_pose.translation().x() = 6.0;
  loop.information = Matrix6d::Identity() * drive.loop_information;
  backend.addLoopClosure(loop);
  backend.update(true);
  if (dump_dir) {
    EXPECT_TRUE(dumpGraph(backend, *dump_dir).success);
  }
  std::vector<double> xs_out;
  for (const auto& kf : backend.trajectory()) xs_out.push_back(kf.pose.translation().x());
  return xs_out;
}

double keyframe3X(bool reanchored, std::string* dump_dir = nullptr) {
  Drive drive;
  drive.reanchored = reanchored;
  return optimisedX(drive, dump_dir).back();
}

}  // namespace

TEST(ReanchoredKeyframe, AWeakOdometryEdgeLetsALoopMoveIt) {
  const double weak = keyframe3X(true), normal = keyframe3X(false);
  std::printf("[reanchored] keyframe 3 at x = %.3f (re-anchored) vs %.3f (normal edge)\n", weak,
              normal);
  EXPECT_NEAR(weak, 6.0, 0.1);
  EXPECT_GT(normal, 6.3) << "a normal odometry edge (cm-level) outweighs the loop";
}

// Keyframe 2's match says its step along x is known to 1.6 mm (Hessian 4e5 per m^2): with the
// Hessian as evidence a stiff loop's 1.5 m correction leaves that step alone and is taken up by
// the others; without it (weight 0) the loop shortens every step.
TEST(ReanchoredKeyframe, AHessianHoldsTheStepItConstrains) {
  Drive drive;
  drive.loop_information = 1e6;  // 1 mm, taken whole (no kernel)
  drive.loop_kernel = "none";
  const std::vector<double> off = optimisedX(drive);
  drive.hessian_weight = 1.0;
  const std::vector<double> on = optimisedX(drive);
  ASSERT_EQ(off.size(), 4u);
  ASSERT_EQ(on.size(), 4u);
  const double step_off = off[2] - off[1], step_on = on[2] - on[1];
  std::printf("[hessian] step 1->2 (odometry 2.000 m): %.4f m without, %.4f m with its Hessian\n",
              step_off, step_on);
  EXPECT_LT(step_off, 1.9) << "without the Hessian the loop shortens every step";
  EXPECT_NEAR(step_on, 2.0, 0.01);
  EXPECT_LT(on[3] - on[2], off[3] - off[2]) << "the other steps take the correction";
  // A match 0.3 m ahead of the motion model's prediction (a deskew by the wrong motion) is held
  // neither by its Hessian nor by its fitness along x: that step takes most of the correction.
  drive.prediction_error = 0.3;
  const std::vector<double> missed = optimisedX(drive);
  std::printf("[hessian] ... %.4f m when the match lay 0.3 m ahead of the prediction\n",
              missed[2] - missed[1]);
  EXPECT_LT(missed[2] - missed[1], 1.0);
  EXPECT_GT(missed[1] - missed[0], 1.9) << "the other steps keep their length";
}

TEST(ReanchoredKeyframe, TheFlagSurvivesDumpAndReplay) {
  const std::string dir = (std::filesystem::temp_directory_path() / "ogs_reanchored_dump").string();
  keyframe3X(true, const_cast<std::string*>(&dir));
  GraphDump dump;
  std::string error;
  ASSERT_TRUE(readGraphDump(dir, dump, &error)) << error;
  ASSERT_EQ(dump.keyframes.size(), 4u);
  EXPECT_FALSE(dump.keyframes[2].reanchored);
  EXPECT_TRUE(dump.keyframes[3].reanchored);
  // Keyframes without an IMU attitude ("nan nan") keep their fitness (they lost it before).
  EXPECT_DOUBLE_EQ(dump.keyframes[1].odom_fitness, 0.05);
  EXPECT_FALSE(dump.keyframes[1].gravity_roll_pitch);
  // The odometry match's Hessian too (zero: none was given).
  EXPECT_TRUE(dump.keyframes[2].odom_hessian.isApprox(someHessian(), 1e-12));
  EXPECT_TRUE(dump.keyframes[1].odom_hessian.isZero());
  EXPECT_DOUBLE_EQ(dump.keyframes[2].odom_prediction_error.x(), 0.0005);
  std::filesystem::remove_all(dir);
}
