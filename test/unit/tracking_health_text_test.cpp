// The tracking-health label of the rviz view (scan_matching's tracking_health_marker): its text
// and colour per level, and when TrackingHealthDisplay says it is worth publishing (level
// changes, keyframes, a held recovery, a lost track's counter once a second).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "frontend_test_utils.h"
#include "osm_graph_slam/odometry/tracking_health.h"

using namespace osm_graph_slam;

namespace {

/// One scan through TrackingHealth and the display, as the nodelet does it.
struct Feed {
  TrackingHealth health{3.0};
  TrackingHealthDisplay display{5.0, 1.0};
  std::vector<std::pair<double, std::string>> published;  ///< (stamp, text)

  void scan(double stamp, TrackStatus status, bool new_keyframe) {
    health.update(stamp, test::trackResult(status, new_keyframe));
    if (const auto label = display.update(stamp, health, new_keyframe))
      published.emplace_back(stamp, label->text);
  }
};

}  // namespace

TEST(TrackingHealthLabel, TextAndColourPerLevel) {
  const auto ok = trackingHealthLabel(TrackingHealthLevel::kOk, 12.0);
  EXPECT_EQ(ok.level, TrackingHealthLevel::kOk);
  EXPECT_EQ(ok.text, "tracking: OK");
  EXPECT_GT(ok.g, 0.8f);  // green
  EXPECT_LT(ok.r, 0.5f);
  EXPECT_LT(ok.b, 0.5f);

  const auto recovered = trackingHealthLabel(TrackingHealthLevel::kRecovered, 1.23);
  EXPECT_EQ(recovered.text, "tracking: RECOVERED (gap 1.2 s)");
  EXPECT_GT(recovered.r, 0.8f);  // yellow
  EXPECT_GT(recovered.g, 0.7f);
  EXPECT_LT(recovered.b, 0.3f);

  const auto lost = trackingHealthLabel(TrackingHealthLevel::kLost, 4.0);
  EXPECT_EQ(lost.text, "tracking: LOST 4.0 s");
  EXPECT_GT(lost.r, 0.8f);  // red
  EXPECT_LT(lost.g, 0.3f);
  EXPECT_LT(lost.b, 0.3f);

  // Nonsense durations never print as such.
  EXPECT_EQ(trackingHealthLabel(TrackingHealthLevel::kLost, -2.0).text, "tracking: LOST 0.0 s");
  EXPECT_EQ(
      trackingHealthLabel(TrackingHealthLevel::kRecovered, std::numeric_limits<double>::quiet_NaN())
          .text,
      "tracking: RECOVERED (gap 0.0 s)");
  EXPECT_STREQ(toString(TrackingHealthLevel::kOk), "ok");
  EXPECT_STREQ(toString(TrackingHealthLevel::kRecovered), "recovered");
  EXPECT_STREQ(toString(TrackingHealthLevel::kLost), "lost");
}

TEST(TrackingHealthLabel, RecoveryGapOnlyOnTheRecoveringKeyframe) {
  TrackingHealth h(3.0);
  h.update(0.0, test::trackResult(TrackStatus::kFirstKeyframe, true));
  EXPECT_FALSE(h.lastRecoveryGap()) << "the first keyframe recovers nothing";
  h.update(0.5, test::trackResult(TrackStatus::kMatched, true, 1));
  EXPECT_FALSE(h.lastRecoveryGap()) << "a verified keyframe on time is no recovery";
  for (int i = 6; i <= 10; ++i)
    h.update(i / 10.0, test::trackResult(TrackStatus::kMatchFailed, false));
  h.update(1.1, test::trackResult(TrackStatus::kReanchored, true, 2));
  ASSERT_TRUE(h.lastRecoveryGap());
  EXPECT_NEAR(*h.lastRecoveryGap(), 0.6, 1e-9);
  h.update(1.2, test::trackResult(TrackStatus::kMatched, false));
  EXPECT_FALSE(h.lastRecoveryGap()) << "only the scan that recovered carries the gap";
  // Lost (no keyframe for more than 3 s), then a verified keyframe ends the span.
  h.update(4.5, test::trackResult(TrackStatus::kMatchFailed, false));
  EXPECT_EQ(h.state(), TrackingState::kLost);
  EXPECT_FALSE(h.lastRecoveryGap());
  h.update(5.0, test::trackResult(TrackStatus::kMatched, true, 3));
  ASSERT_TRUE(h.lastRecoveryGap());
  EXPECT_NEAR(*h.lastRecoveryGap(), 3.9, 1e-9);
  h.update(5.1, test::trackResult(TrackStatus::kRejectedCloud, false));
  EXPECT_FALSE(h.lastRecoveryGap());
}

TEST(TrackingHealthDisplay, PublishesOnChangesKeyframesAndOncePerSecondWhileLost) {
  Feed f;
  // 10 Hz, a keyframe every 5 scans: the first scan and every keyframe publish "OK".
  f.scan(0.0, TrackStatus::kFirstKeyframe, true);
  for (int i = 1; i <= 10; ++i) f.scan(i / 10.0, TrackStatus::kMatched, i % 5 == 0);
  const std::vector<std::pair<double, std::string>> healthy = {
      {0.0, "tracking: OK"}, {0.5, "tracking: OK"}, {1.0, "tracking: OK"}};
  EXPECT_EQ(f.published, healthy);

  // Five failures, a re-anchored keyframe 0.6 s after the last one: "RECOVERED", held 5 s.
  f.published.clear();
  for (int i = 11; i <= 15; ++i) f.scan(i / 10.0, TrackStatus::kMatchFailed, false);
  EXPECT_TRUE(f.published.empty()) << "failed matches within the limit change nothing on screen";
  f.scan(1.6, TrackStatus::kReanchored, true);
  ASSERT_EQ(f.published.size(), 1u);
  EXPECT_EQ(f.published[0].second, "tracking: RECOVERED (gap 0.6 s)");
  EXPECT_EQ(f.display.label().level, TrackingHealthLevel::kRecovered);
  for (int i = 17; i <= 65; ++i) f.scan(i / 10.0, TrackStatus::kMatched, i % 20 == 0);
  // Still held at 6.5 s (4.9 s after the recovery), republished with the keyframes at 2.0, 4.0
  // and 6.0 s.
  ASSERT_EQ(f.published.size(), 4u);
  for (const auto& p : f.published) EXPECT_EQ(p.second, "tracking: RECOVERED (gap 0.6 s)");
  // 5.0 s after the recovery (6.6 s, or 6.7 s as the stamps round): back to OK, a change.
  f.scan(6.6, TrackStatus::kMatched, false);
  f.scan(6.7, TrackStatus::kMatched, false);
  ASSERT_EQ(f.published.size(), 5u);
  EXPECT_EQ(f.published.back().second, "tracking: OK");
  EXPECT_NEAR(f.published.back().first, 6.65, 0.051);

  // No keyframe after 6.0 s: lost at 9.1 s, the counter refreshed every second, then a verified
  // keyframe at 12.0 s recovers it (gap 6.0 s).
  f.published.clear();
  for (int i = 68; i <= 119; ++i) f.scan(i / 10.0, TrackStatus::kMatchFailed, false);
  const std::vector<std::string> lost = {"tracking: LOST 3.1 s", "tracking: LOST 4.1 s",
                                         "tracking: LOST 5.1 s"};
  ASSERT_EQ(f.published.size(), lost.size());
  for (size_t i = 0; i < lost.size(); ++i) EXPECT_EQ(f.published[i].second, lost[i]);
  EXPECT_NEAR(f.published[0].first, 9.1, 1e-9);
  f.scan(12.0, TrackStatus::kMatched, true);
  EXPECT_EQ(f.published.back(),
            std::make_pair(12.0, std::string("tracking: RECOVERED (gap 6.0 s)")));
  EXPECT_EQ(f.health.stats().lost_events, 1u);
}
