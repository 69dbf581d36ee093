#include <gtest/gtest.h>

#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/lines/line_geometry.h"

using namespace osm_graph_slam;

namespace {

Building square(int64_t id, double x, double y, double size) {
  Building b;
  b.id = id;
  b.outline_enu = {{x, y}, {x + size, y}, {x + size, y + size}, {x, y + size}};
  return b;
}

Building transformed(const Building& b, const Pose2& T) {
  Building out = b;
  for (auto& v : out.outline_enu) v = T.transform(v);
  return out;
}

}  // namespace

TEST(BuildingEval, TranslationAndRotationErrors) {
  const std::vector<Building> truth = {square(1, 0, 0, 10), square(2, 30, 0, 8)};
  // Building 1 shifted by 0.5 m; building 2 rotated 2 degrees about its first corner.
  const double rot = 2.0 * M_PI / 180.0;
  const Pose2 about_corner = Pose2(30, 0, 0) * Pose2(0, 0, rot) * Pose2(-30, 0, 0);
  const std::vector<Building> est = {transformed(truth[0], Pose2(0.3, 0.4, 0.0)),
                                     transformed(truth[1], about_corner), square(99, 0, 50, 5)};
  const BuildingErrors e = evaluateBuildings(est, truth);
  EXPECT_EQ(e.matched, 2u);
  EXPECT_NEAR(e.max_corner_error, 0.5, 1e-9);
  EXPECT_NEAR(e.mean_corner_error, 0.25, 1e-9);  // building 2's reference corner did not move
  EXPECT_NEAR(e.mean_heading_error_deg, 1.0, 1e-6);
}

TEST(BuildingEval, TheCommonOffsetIsSeparatedFromTheShape) {
  // Three buildings shifted alike by (1, 0) m, one of them 0.3 m further north: the set sits
  // 1.0 m (and 0.1 m north) off as a whole; around that, the shape errs 0.2, 0.1, 0.1 m.
  const std::vector<Building> truth = {square(1, 0, 0, 10), square(2, 30, 0, 8),
                                       square(3, 60, 0, 6)};
  const std::vector<Building> est = {transformed(truth[0], Pose2(1.0, 0.3, 0.0)),
                                     transformed(truth[1], Pose2(1.0, 0.0, 0.0)),
                                     transformed(truth[2], Pose2(1.0, 0.0, 0.0))};
  const BuildingErrors e = evaluateBuildings(est, truth);
  EXPECT_NEAR(e.common_offset, std::hypot(1.0, 0.1), 1e-9);
  EXPECT_NEAR(e.mean_corner_error_shape, (0.2 + 0.1 + 0.1) / 3.0, 1e-9);
  EXPECT_GT(e.mean_corner_error, 1.0);
  // A set shifted as a whole has no shape error.
  const BuildingErrors shifted = evaluateBuildings(
      {transformed(truth[0], Pose2(2, -1, 0)), transformed(truth[1], Pose2(2, -1, 0))}, truth);
  EXPECT_NEAR(shifted.mean_corner_error_shape, 0.0, 1e-9);
  EXPECT_NEAR(shifted.common_offset, std::sqrt(5.0), 1e-9);
}

TEST(BuildingEval, VertexCountMismatchIsReportedNotCompared) {
  Building a = square(5, 0, 0, 4);
  Building b = a;
  b.outline_enu.pop_back();
  const BuildingErrors e = evaluateBuildings({b}, {a});
  EXPECT_EQ(e.matched, 0u);
  EXPECT_EQ(e.vertex_mismatch, 1u);
}

TEST(BuildingEval, OverlapAreaAndPairs) {
  const Building a = square(1, 0, 0, 10), b = square(2, 9, 9, 10), c = square(3, 10, 0, 5);
  EXPECT_NEAR(polygonOverlapArea(a.outline_enu, b.outline_enu), 1.0, 1e-9);
  // Clockwise input gives the same area.
  Polygon2 cw(b.outline_enu.rbegin(), b.outline_enu.rend());
  EXPECT_NEAR(polygonOverlapArea(a.outline_enu, cw), 1.0, 1e-9);
  // a and c share a wall: zero area, not an overlap.
  EXPECT_NEAR(polygonOverlapArea(a.outline_enu, c.outline_enu), 0.0, 1e-9);
  const auto pairs = findOverlappingBuildings({a, b, c});
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], std::make_pair(size_t{0}, size_t{1}));
  EXPECT_DOUBLE_EQ(polygonOverlapArea({}, a.outline_enu), 0.0);
}
