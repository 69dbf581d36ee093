// LocalizationHandover: which keyframes are mapped, when, and with which localised poses.
#include <gtest/gtest.h>

#include "osm_graph_slam/slam/localization_handover.h"

namespace osm_graph_slam {
namespace {

/// A drive along x at 10 m/s, a scan every 0.1 s, a keyframe every 0.5 s (5 m).
KeyframeInput keyframeAt(uint64_t id) {
  KeyframeInput kf;
  kf.id = id;
  kf.stamp = 0.5 * static_cast<double>(id);
  kf.odom_pose.translation().x() = 5.0 * static_cast<double>(id);
  return kf;
}

/// The map pose the localiser reports: odometry shifted by a known placement.
Eigen::Isometry3d mapPoseAt(double stamp) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() << 100.0 + 10.0 * stamp, 50.0, 0.0;
  return pose;
}

/// Scans from `from` to `to` (inclusive, 0.1 s apart), tracked until `tracked_until`.
void localize(LocalizationHandover& h, double from, double to, double tracked_until) {
  for (int i = static_cast<int>(std::lround(from * 10)); i <= std::lround(to * 10); ++i) {
    const double stamp = 0.1 * i;
    h.addLocalization(stamp, stamp <= tracked_until + 1e-9, mapPoseAt(stamp));
  }
}

TEST(LocalizationHandover, HoldsEveryKeyframeWhileTheLocaliserTracks) {
  LocalizationHandover h(LocalizationHandoverParams{});
  localize(h, 0.0, 10.0, 10.0);
  for (uint64_t id = 0; id <= 20; ++id) h.addKeyframe(keyframeAt(id));
  EXPECT_TRUE(h.release().empty());
  EXPECT_FALSE(h.mapping());
  // The last three tracked keyframes may still be mapped (the ties); the ones before never are.
  EXPECT_EQ(h.fate(17), LocalizationHandover::Fate::kLocalized);
  EXPECT_EQ(h.fate(18), LocalizationHandover::Fate::kWaiting);
  EXPECT_EQ(h.fate(21), LocalizationHandover::Fate::kWaiting);
}

TEST(LocalizationHandover, MapsFromTheLastTiesOnceTheLocaliserHasLeftTheMap) {
  LocalizationHandoverParams params;
  params.leave_after = 2.0;
  params.ties = 3;
  LocalizationHandover h(params);
  // Tracked until 6.0 s, not from 6.1 s on: the hand-over comes with the first keyframe 2 s
  // later (8.5 s).
  localize(h, 0.0, 8.0, 6.0);
  for (uint64_t id = 0; id <= 16; ++id) h.addKeyframe(keyframeAt(id));  // up to 8.0 s
  EXPECT_TRUE(h.release().empty());
  localize(h, 8.1, 8.5, 6.0);
  h.addKeyframe(keyframeAt(17));  // 8.5 s
  const std::vector<HandoverKeyframe> out = h.release();
  ASSERT_TRUE(h.mapping());
  EXPECT_NEAR(*h.handoverStamp(), 8.5, 1e-9);
  // The ties are the keyframes at 5.0, 5.5 and 6.0 s, then every keyframe after them.
  ASSERT_EQ(out.size(), 8u);
  for (size_t i = 0; i < out.size(); ++i) EXPECT_EQ(out[i].keyframe.id, 10 + i);
  for (size_t i = 0; i < 3; ++i) {
    ASSERT_TRUE(out[i].localized.has_value()) << i;
    EXPECT_TRUE(out[i].localized->isApprox(mapPoseAt(out[i].keyframe.stamp)));
  }
  for (size_t i = 3; i < out.size(); ++i) EXPECT_FALSE(out[i].localized.has_value()) << i;
  EXPECT_EQ(h.keyframesLocalized(), 10u);  // 0 .. 4.5 s: covered by the saved map
  // Segments, floors and loops of those keyframes are dropped, the others' go into the graph.
  EXPECT_EQ(h.fate(9), LocalizationHandover::Fate::kLocalized);
  EXPECT_EQ(h.fate(10), LocalizationHandover::Fate::kMapped);
  EXPECT_EQ(h.fate(30), LocalizationHandover::Fate::kMapped);
  // From then on every keyframe as it comes.
  h.addKeyframe(keyframeAt(18));
  const std::vector<HandoverKeyframe> next = h.release();
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].keyframe.id, 18u);
}

TEST(LocalizationHandover, ABriefLossOfTheMapIsNoHandover) {
  LocalizationHandover h(LocalizationHandoverParams{});
  localize(h, 0.0, 4.0, 4.0);
  localize(h, 4.1, 5.5, 0.0);  // 1.5 s not tracked (registrations refused) ...
  localize(h, 5.6, 9.0, 9.0);  // ... then tracked again
  for (uint64_t id = 0; id <= 18; ++id) h.addKeyframe(keyframeAt(id));
  EXPECT_TRUE(h.release().empty());
  EXPECT_FALSE(h.mapping());
}

TEST(LocalizationHandover, AKeyframeWaitsForTheLocaliserToDoItsScan) {
  LocalizationHandover h(LocalizationHandoverParams{});
  localize(h, 0.0, 1.0, 1.0);
  // The tracker is ahead: keyframes up to 5 s, the localiser's results only up to 1 s.
  for (uint64_t id = 0; id <= 10; ++id) h.addKeyframe(keyframeAt(id));
  EXPECT_TRUE(h.release().empty());
  // Its results for the later scans say it never tracked them: the hand-over with the keyframe
  // at 3.5 s, and the keyframes up to 5 s it waited for are all released, the ties first.
  localize(h, 1.1, 5.0, 1.0);
  const std::vector<HandoverKeyframe> out = h.release();
  ASSERT_TRUE(h.mapping());
  EXPECT_NEAR(*h.handoverStamp(), 3.5, 1e-9);
  ASSERT_EQ(out.size(), 11u);  // ties at 0.0, 0.5, 1.0 s and the keyframes 1.5 .. 5.0 s
  EXPECT_EQ(out.front().keyframe.id, 0u);
  EXPECT_EQ(out.back().keyframe.id, 10u);
  EXPECT_TRUE(out[2].localized.has_value());
  EXPECT_FALSE(out[3].localized.has_value());
}

TEST(LocalizationHandover, ALocaliserThatNeverTrackedHandsOverWithoutTies) {
  LocalizationHandover h(LocalizationHandoverParams{});
  localize(h, 0.0, 3.0, -1.0);  // never localised (a start off the map)
  for (uint64_t id = 0; id <= 6; ++id) h.addKeyframe(keyframeAt(id));
  const std::vector<HandoverKeyframe> out = h.release();
  ASSERT_TRUE(h.mapping());
  ASSERT_EQ(out.size(), 7u);  // every keyframe from the start: the session starts unplaced
  for (const auto& kf : out) EXPECT_FALSE(kf.localized.has_value());
}

}  // namespace
}  // namespace osm_graph_slam
