#include <gtest/gtest.h>

#include "osm_graph_slam/common/geometry2d.h"
#include "osm_graph_slam/common/logger.h"

using namespace osm_graph_slam;

TEST(Geometry2d, WrapAngleStaysInHalfOpenInterval) {
  EXPECT_NEAR(wrapAngle(3.0 * M_PI), M_PI, 1e-12);
  EXPECT_NEAR(wrapAngle(-3.0 * M_PI), M_PI, 1e-12);
  EXPECT_NEAR(wrapAngle(0.5), 0.5, 1e-15);
  EXPECT_NEAR(wrapAngle(2.0 * M_PI + 0.25), 0.25, 1e-12);
}

TEST(Geometry2d, PoseComposeAndInverse) {
  const Pose2 a(1.0, 2.0, 0.3), b(-0.5, 4.0, -1.2);
  const Pose2 ab = a * b;
  const Eigen::Vector2d p(3.0, -7.0);
  EXPECT_TRUE((ab.transform(p) - a.transform(b.transform(p))).norm() < 1e-12);
  const Pose2 id = a * a.inverse();
  EXPECT_NEAR(id.x, 0.0, 1e-12);
  EXPECT_NEAR(id.y, 0.0, 1e-12);
  EXPECT_NEAR(id.theta, 0.0, 1e-12);
}

TEST(Geometry2d, SegmentBasics) {
  const LineSegment2 s({0.0, 0.0}, {3.0, 4.0});
  EXPECT_DOUBLE_EQ(s.length(), 5.0);
  EXPECT_NEAR(s.direction().x(), 0.6, 1e-15);
  const LineSegment2 t = s.transformed(Pose2(1.0, 0.0, M_PI / 2));
  EXPECT_NEAR(t.end.x(), -3.0, 1e-12);
  EXPECT_NEAR(t.end.y(), 3.0, 1e-12);
  // A degenerate segment still has a unit direction (no NaN leaks into matchers).
  EXPECT_DOUBLE_EQ(LineSegment2().direction().norm(), 1.0);
}

TEST(Logger, WarnOnceLogsOnlyFirstUntilReset) {
  int count = 0;
  Logger log([&](LogLevel level, const std::string&) { count += level == LogLevel::kWarn; });
  log.warnOnce("overpass", "timeout");
  log.warnOnce("overpass", "timeout");
  EXPECT_EQ(count, 1);
  log.resetOnce("overpass");
  log.warnOnce("overpass", "timeout");
  EXPECT_EQ(count, 2);
}
