// The line stage on real HDL-64E scans (KITTI 00, frames 94 and 95, ../shared/data).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "test_data.h"

using namespace osm_graph_slam;

namespace {

constexpr double kDeg = M_PI / 180.0;

PointCloud readScan(const std::string& name) {
  PointCloud cloud;
  std::string error;
  EXPECT_TRUE(readKittiBin(test::sharedDataPath("kitti00/" + name), cloud, &error)) << error;
  return cloud;
}

std::vector<LineSegment2> segmentsOf(const PointCloud& cloud) {
  return LineSegmentExtractor().extract(*WallPointExtractor().extract(cloud));
}

/// Ground-truth planar motion 94 -> 95 (points of 95 in 94's frame), from the file's 3x4 matrix.
bool readGroundTruth(Pose2& out) {
  std::ifstream in(test::sharedDataPath("kitti00/gt_relative_lidar.txt"));
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    int a, b;
    double m[12];
    ss >> a >> b;
    for (double& v : m) ss >> v;
    if (!ss || a != 94 || b != 95) continue;
    out = Pose2(m[3], m[7], std::atan2(m[4], m[0]));
    return true;
  }
  return false;
}

}  // namespace

TEST(LineKitti, SegmentsLieOnVerticalStructure) {
  const std::string path = test::sharedDataPath("kitti00/000094.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  const PointCloud cloud = readScan("000094.bin");
  WallPointStats wstats;
  const auto walls = WallPointExtractor().extract(cloud, &wstats);
  LineSegmentStats lstats;
  const auto segments = LineSegmentExtractor().extract(*walls, &lstats);
  std::vector<double> lengths;
  for (const auto& s : segments) lengths.push_back(s.length());
  std::sort(lengths.begin(), lengths.end());
  double total = 0.0;
  for (double l : lengths) total += l;
  std::printf(
      "[kitti 94] %zu points -> %zu above horizon -> %zu voxels -> %zu wall points -> %zu "
      "segments, length min %.2f median %.2f max %.2f total %.1f m\n",
      wstats.input, wstats.above_horizon, wstats.voxelized, wstats.walls, segments.size(),
      lengths.front(), lengths[lengths.size() / 2], lengths.back(), total);
  ASSERT_GE(segments.size(), 10u);
  EXPECT_LE(segments.size(), 64u);
  EXPECT_GE(lengths.back(), 8.0);  // at least one long facade
  EXPECT_GE(total, 80.0);

  // Vertical structure: the raw scan has points spread over >= 1 m of height within 0.15 m of
  // (at least 90 % of) the segments — walls, not the road, car roofs or a canopy edge.
  int vertical = 0;
  for (const auto& s : segments) {
    const Eigen::Vector2d u = s.direction(), n(-u.y(), u.x());
    float zmin = HUGE_VALF, zmax = -HUGE_VALF;
    for (const auto& p : cloud) {
      const Eigen::Vector2d q = Eigen::Vector2d(p.x, p.y) - s.start;
      const double t = q.dot(u);
      if (t < 0.0 || t > s.length() || std::abs(q.dot(n)) > 0.15) continue;
      zmin = std::min(zmin, p.z);
      zmax = std::max(zmax, p.z);
    }
    if (zmax - zmin >= 1.0)
      ++vertical;
    else
      std::printf("  low: length %.2f at range %.1f, z %.2f..%.2f\n", s.length(),
                  s.midpoint().norm(), zmin, zmax);
  }
  std::printf("[kitti 94] %d of %zu segments on >= 1 m tall structure\n", vertical,
              segments.size());
  EXPECT_GE(vertical, int(0.9 * segments.size()));
}

TEST(LineKitti, ScanToScanMatchingRecoversGroundTruthMotion) {
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000095.bin"));
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/gt_relative_lidar.txt"));
  Pose2 gt;
  ASSERT_TRUE(readGroundTruth(gt));
  const auto seg94 = segmentsOf(readScan("000094.bin"));
  const auto seg95 = segmentsOf(readScan("000095.bin"));
  // Source: scan 95, target: scan 94, no prior motion (identity guess).
  const LineMatchResult r = LineMatcher().matchGlobal(seg95, seg94, Pose2());
  std::printf(
      "[kitti 95->94] (%.4f, %.4f, %.4f deg) vs gt (%.4f, %.4f, %.4f deg): error %.3f m "
      "%.3f deg, fitness %.1f matched %d/%zu %s, edge pairs %zu/%zu evaluated %zu+%zu, "
      "%.2f ms\n",
      r.transform.x, r.transform.y, r.transform.theta / kDeg, gt.x, gt.y, gt.theta / kDeg,
      std::hypot(r.transform.x - gt.x, r.transform.y - gt.y),
      std::abs(wrapAngle(r.transform.theta - gt.theta)) / kDeg, r.fitness, r.matched_segments,
      seg95.size(), toString(r.feature), r.stats.edge_pairs_in_bounds, r.stats.edge_pairs_total,
      r.stats.hypotheses_evaluated, r.stats.line_pairs_evaluated, r.stats.ms);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_LT(std::hypot(r.transform.x - gt.x, r.transform.y - gt.y), 0.10);
  EXPECT_LT(std::abs(wrapAngle(r.transform.theta - gt.theta)), 0.5 * kDeg);
  EXPECT_FALSE(r.two_dof);
}
