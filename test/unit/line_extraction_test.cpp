// Wall points and RANSAC line segments: geometry, determinism and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/sim/wall_scan_simulator.h"

using namespace osm_graph_slam;

namespace {

PointT point(double x, double y, double z) {
  PointT p;
  p.x = float(x), p.y = float(y), p.z = float(z), p.intensity = 0.0f;
  return p;
}

/// Distance of p to the nearest of the walls.
double distanceToWalls(const Eigen::Vector2d& p, const std::vector<LineSegment2>& walls) {
  double best = HUGE_VAL;
  for (const auto& w : walls) best = std::min(best, pointSegmentDistance(p, w));
  return best;
}

}  // namespace

TEST(WallPointExtractor, KeepsWallsDropsGroundRoofAndBelowHorizon) {
  PointCloud cloud;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 4000; ++i) {
    cloud.push_back(point(10.0 + 0.01 * u(rng), -8 + 16 * u(rng), -1.0 + 6 * u(rng)));  // wall x=10
    cloud.push_back(point(-8 + 16 * u(rng), -8 + 16 * u(rng), -1.7));                   // ground
    cloud.push_back(point(-12 + 4 * u(rng), -8 + 16 * u(rng), 3.0 + 0.01 * u(rng)));  // canopy/roof
  }
  WallPointStats stats;
  const auto walls = WallPointExtractor().extract(cloud, &stats);
  ASSERT_GT(walls->size(), 100u);
  size_t on_wall = 0;
  for (const auto& p : *walls) {
    EXPECT_EQ(p.z, 0.0f);  // flattened
    on_wall += std::abs(p.x - 10.0f) < 0.15f;
  }
  EXPECT_GE(double(on_wall), 0.97 * walls->size());  // the horizontal roof is rejected
  EXPECT_EQ(stats.walls, walls->size());
  EXPECT_LT(stats.above_horizon, stats.input);  // ground and lower wall part cut first
}

TEST(WallPointExtractor, PclBaselineAgreesWithNanoflann) {
  const auto scene = makeStreetScene(8, 2);
  const auto scan = simulateWallScan(scene, Pose2(0, 0, 0.1), WallScanParams());
  WallPointExtractorParams pcl_params;
  pcl_params.normal_backend = "pcl";
  const auto ours = WallPointExtractor().extract(*scan);
  const auto ref = WallPointExtractor(pcl_params).extract(*scan);
  ASSERT_GT(ref->size(), 500u);
  EXPECT_NEAR(double(ours->size()), double(ref->size()), 0.05 * ref->size());
}

TEST(WallPointExtractor, BadInputGivesEmptyOrFiniteOutput) {
  const WallPointExtractor ex;
  EXPECT_TRUE(ex.extract(PointCloud())->empty());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointCloud bad;
  for (int i = 0; i < 100; ++i) bad.push_back(point(nan, 1, 1));
  for (int i = 0; i < 100; ++i) bad.push_back(point(5, 5, 1));            // duplicates
  for (int i = 0; i < 100; ++i) bad.push_back(point(5 + 0.1 * i, 5, 1));  // collinear
  bad.push_back(point(std::numeric_limits<float>::infinity(), 0, 1));
  WallPointStats stats;
  const auto out = ex.extract(bad, &stats);
  EXPECT_EQ(stats.finite, 200u);
  for (const auto& p : *out) EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y));
}

TEST(LineSegmentExtractor, RecoversWallsOfASimulatedStreet) {
  const auto scene = makeStreetScene(10, 5);
  const Pose2 sensor(0.0, 0.0, 0.0);
  const auto scan = simulateWallScan(scene, sensor, WallScanParams());
  const auto walls = WallPointExtractor().extract(*scan);
  const auto segments = LineSegmentExtractor().extract(*walls);
  ASSERT_GE(segments.size(), 8u);
  const auto map = buildingWalls(scene);
  double total = 0.0;
  for (const auto& s : segments) {
    // Endpoints on a real wall (noise 2 cm, merge grid 15 cm): within 10 cm.
    EXPECT_LT(distanceToWalls(s.start, map), 0.10);
    EXPECT_LT(distanceToWalls(s.end, map), 0.10);
    EXPECT_GE(s.length(), 1.0);
    EXPECT_GE(s.support, 10u);
    total += s.length();
  }
  EXPECT_GT(total, 60.0);
}

TEST(LineSegmentExtractor, TwoCollinearWallsWithAGapGiveTwoSegments) {
  std::vector<Eigen::Vector2d> pts;
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 0.01);
  for (double x = 0.0; x <= 8.0; x += 0.05) pts.emplace_back(x, 5.0 + n(rng));
  for (double x = 11.0; x <= 15.0; x += 0.05) pts.emplace_back(x, 5.0 + n(rng));
  const auto segs = LineSegmentExtractor().extract(pts);
  ASSERT_EQ(segs.size(), 2u);  // the Euclidean clustering splits the 3 m gap
  const LineSegment2& longer = segs[0].length() > segs[1].length() ? segs[0] : segs[1];
  EXPECT_NEAR(longer.length(), 8.0, 0.1);
  EXPECT_NEAR(longer.midpoint().y(), 5.0, 0.01);
}

TEST(LineSegmentExtractor, DeterministicForAGivenSeed) {
  const auto scene = makeStreetScene(12, 9);
  const auto scan = simulateWallScan(scene, Pose2(3, 0, 0), WallScanParams());
  const auto walls = WallPointExtractor().extract(*scan);
  const auto a = LineSegmentExtractor().extract(*walls);
  const auto b = LineSegmentExtractor().extract(*walls);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].start, b[i].start);
    EXPECT_EQ(a[i].end, b[i].end);
  }
}

TEST(LineSegmentExtractor, BadInputNeverCrashes) {
  const LineSegmentExtractor ex;
  EXPECT_TRUE(ex.extract(std::vector<Eigen::Vector2d>{}).empty());
  const double nan = std::nan("");
  std::vector<Eigen::Vector2d> nans(500, Eigen::Vector2d(nan, 1.0));
  EXPECT_TRUE(ex.extract(nans).empty());
  std::vector<Eigen::Vector2d> dup(5000, Eigen::Vector2d(2.0, 3.0));  // one point, 5000 times
  EXPECT_TRUE(ex.extract(dup).empty());
  std::vector<Eigen::Vector2d> huge = {{1e300, 0}, {-1e300, 0}, {0, 1e20}};
  EXPECT_TRUE(ex.extract(huge).empty());
  std::vector<Eigen::Vector2d> collinear;  // one perfect line plus NaN noise
  for (int i = 0; i < 200; ++i) collinear.emplace_back(0.05 * i, 0.0);
  for (int i = 0; i < 50; ++i) collinear.emplace_back(nan, nan);
  const auto segs = ex.extract(collinear);
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_NEAR(segs[0].length(), 9.95, 0.1);
}

TEST(LineGeometry, DistancesAndEdges) {
  const LineSegment2 target({0, 0}, {10, 0});
  // Without coverage: endpoints averaged; the overhanging endpoint uses the target endpoint.
  EXPECT_NEAR(segmentDistanceNoCoverage(LineSegment2({2, 1}, {4, 1}), target), 1.0, 1e-12);
  EXPECT_NEAR(segmentDistanceNoCoverage(LineSegment2({-3, 0}, {1, 0}), target), 1.5, 1e-12);
  // With coverage: a long source over a short target counts only the overlapping part.
  const CoverageDistance c =
      segmentDistanceWithCoverage(LineSegment2({-5, 0.2}, {15, 0.2}), LineSegment2({2, 0}, {6, 0}));
  EXPECT_NEAR(c.distance, 0.2, 1e-12);
  EXPECT_NEAR(c.coverage, 4.0, 1e-12);
  // A rectangle corner seen as two walls stopping 0.4 m short: one angular edge at the corner.
  const auto edges =
      extractEdges({LineSegment2({0.4, 0}, {8, 0}), LineSegment2({0, 0.4}, {0, 5})}, EdgeParams());
  ASSERT_EQ(edges.size(), 1u);
  EXPECT_FALSE(edges[0].virtual_edge);
  EXPECT_NEAR(edges[0].corner.norm(), 0.0, 1e-12);
  EXPECT_NEAR(edges[0].opening, M_PI / 2, 1e-12);
  // Two walls 4 m apart whose lines meet: a virtual edge.
  const auto v =
      extractEdges({LineSegment2({4, 0}, {8, 0}), LineSegment2({0, 3}, {0, 6})}, EdgeParams());
  ASSERT_EQ(v.size(), 1u);
  EXPECT_TRUE(v[0].virtual_edge);
  // Parallel walls: no edge.
  EXPECT_TRUE(
      extractEdges({LineSegment2({0, 0}, {8, 0}), LineSegment2({0, 3}, {8, 3})}, EdgeParams())
          .empty());
}
