// A keyframe the tracker re-anchored after a lost track is linked by a weak odometry edge: a loop
// closure can then move it across the gap, where a normal edge would hold it; the flag survives
// dump_graph and replay.
#include <gtest/gtest.h>

#include <filesystem>

#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/map_export.h"

using namespace osm_graph_slam;

namespace {

/// Keyframes every 2 m along x (odometry); keyframe 3 was re-anchored 1.5 m too far (odometry
/// says x = 7.5, truth 6.0) and a loop closure from keyframe 3 to keyframe 0 says 6.0.
double keyframe3X(bool reanchored, std::string* dump_dir = nullptr) {
  GraphBackendParams params;
  params.use_osm = false;
  GraphBackend backend(params);
  const double xs[] = {0.0, 2.0, 4.0, 7.5};
  for (uint64_t i = 0; i < 4; ++i) {
    KeyframeInput kf;
    kf.id = i;
    kf.stamp = 1.0 + i;
    kf.odom_pose.translation().x() = xs[i];
    kf.odom_fitness = 0.05;
    kf.reanchored = reanchored && i == 3;
    backend.addKeyframe(kf);
  }
  LoopClosureInput loop;
  loop.from_id = 3;
  loop.to_id = 0;
  loop.relative_pose.translation().x() = 6.0;
  loop.information = Matrix6d::Identity() * 100.0;  // 10 cm, 0.1 rad
  backend.addLoopClosure(loop);
  backend.update(true);
  if (dump_dir) EXPECT_TRUE(dumpGraph(backend, *dump_dir).success);
  return backend.trajectory().back().pose.translation().x();
}

}  // namespace

TEST(ReanchoredKeyframe, AWeakOdometryEdgeLetsALoopMoveIt) {
  const double weak = keyframe3X(true), normal = keyframe3X(false);
  std::printf("[reanchored] keyframe 3 at x = %.3f (re-anchored) vs %.3f (normal edge)\n", weak,
              normal);
  EXPECT_NEAR(weak, 6.0, 0.1);
  EXPECT_GT(normal, 6.3) << "a normal odometry edge (cm-level) outweighs the loop";
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
  std::filesystem::remove_all(dir);
}
