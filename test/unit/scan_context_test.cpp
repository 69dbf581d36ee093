// Scan Context descriptor and the incremental KD index: rotation invariance of the ring key,
// column-shift equivalence under yaw, yaw recovery within one sector, index correctness.
#include <gtest/gtest.h>

#include <iostream>
#include <random>

#include "osm_graph_slam/common/dynamic_kd_index.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/loop/scan_context.h"
#include "osm_graph_slam/sim/synthetic_world.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

PointCloud rotatedAboutZ(const PointCloud& in, double yaw) {
  PointCloud out = in;
  const float c = std::cos(yaw), s = std::sin(yaw);
  for (auto& p : out.points) {
    const float x = p.x, y = p.y;
    p.x = c * x - s * y;
    p.y = s * x + c * y;
  }
  return out;
}

double angleDiff(double a, double b) {
  return std::abs(std::atan2(std::sin(a - b), std::cos(a - b)));
}

PointCloudPtr townScan(double x, double y, double yaw) {
  static const SyntheticWorld world = makeLoopTown(200.0, 120.0, 14.0, 7);
  return simulateSyntheticScan(world, {x, y}, yaw, SyntheticLidarParams(), 3);
}

// The rotated cloud is the query, the original the candidate: p_query = Rz(yaw) p_cand, so the
// expected descriptor yaw (p_cand = Rz(yaw_sc) p_query) is -yaw.
void expectYawRecovered(const PointCloud& cloud, const ScanContextParams& params) {
  const ScanContext original = computeScanContext(cloud, params);
  const double sector = 2.0 * M_PI / params.num_sectors;
  for (double deg = -180.0; deg < 180.0; deg += 13.7) {
    const double yaw = deg * M_PI / 180.0;
    const ScanContext rotated = computeScanContext(rotatedAboutZ(cloud, yaw), params);
    EXPECT_LT((rotated.ring_key - original.ring_key).norm(), 0.15) << "yaw " << deg;
    const ScanContextMatch m = matchScanContexts(rotated, original, params);
    EXPECT_LT(angleDiff(m.yaw, -yaw), sector) << "yaw " << deg << " got " << m.yaw * 180 / M_PI;
    EXPECT_LT(m.distance, 0.25) << "yaw " << deg;
  }
}

TEST(ScanContext, ExactSectorRotationIsAColumnShift) {
  const PointCloudPtr cloud = townScan(100.0, 1.0, 0.3);
  ScanContextParams params;
  const ScanContext original = computeScanContext(*cloud, params);
  ASSERT_GT(original.occupied_cells, 100);
  for (int k : {1, 7, 30, 45, 59}) {
    const double yaw = k * 2.0 * M_PI / params.num_sectors;
    const ScanContext rotated = computeScanContext(rotatedAboutZ(*cloud, yaw), params);
    // Query column j sees the candidate's column j - k.
    const int shift = params.num_sectors - k;
    int equal = 0;
    for (int r = 0; r < params.num_rings; ++r) {
      for (int j = 0; j < params.num_sectors; ++j) {
        const float a = rotated.cells(r, j);
        const float b = original.cells(r, (j + shift) % params.num_sectors);
        equal += std::abs(a - b) < 1e-3f ? 1 : 0;
      }
    }
    // Only points within float rounding of a sector border may change cell.
    EXPECT_GE(equal, 0.97 * params.num_rings * params.num_sectors) << "k " << k;
    EXPECT_LT(scanContextDistanceAtShift(rotated, original, shift), 0.05) << "k " << k;
    const ScanContextMatch m = matchScanContexts(rotated, original, params);
    EXPECT_EQ(m.shift, shift) << "k " << k;
  }
}

TEST(ScanContext, SyntheticScanYawRecoveredWithinOneSector) {
  ScanContextParams params;
  expectYawRecovered(*townScan(100.0, 1.0, 0.3), params);
  params.sector_search_window = -1;  // exhaustive shift search gives the same answer
  expectYawRecovered(*townScan(200.0, 60.0, 1.9), params);
}

TEST(ScanContext, RealScanYawRecoveredWithinOneSector) {
  const std::string path = test::sharedDataPath("patchwork/000000.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  PointCloud cloud;
  std::string error;
  ASSERT_TRUE(readKittiBin(path, cloud, &error)) << error;
  expectYawRecovered(cloud, ScanContextParams());
}

TEST(ScanContext, RevisitRanksTheSamePlaceFirst) {
  // Database: one scan every 20 m around the town; queries: the same places revisited 1 m to
  // the side with an arbitrary heading. The true place must rank first by descriptor distance.
  ScanContextParams params;
  const auto places = loopTownRoute(200.0, 120.0, 0.0, 20.0, 10.0, 0.0);
  std::vector<ScanContext> database;
  for (const auto& p : places) {
    database.push_back(computeScanContext(*townScan(p.x(), p.y(), p.z()), params));
  }
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  int first = 0;
  double worst_true = 0.0;
  for (size_t i = 0; i < places.size(); ++i) {
    const auto& p = places[i];
    const Eigen::Vector2d side(-std::sin(p.z()), std::cos(p.z()));
    const ScanContext query =
        computeScanContext(*townScan(p.x() + side.x(), p.y() + side.y(), heading(rng)), params);
    size_t best = 0;
    double best_d = 2.0;
    for (size_t j = 0; j < database.size(); ++j) {
      const double d = matchScanContexts(query, database[j], params).distance;
      if (d < best_d) best_d = d, best = j;
    }
    worst_true = std::max(worst_true, matchScanContexts(query, database[i], params).distance);
    first += best == i ? 1 : 0;
  }
  std::cout << "[ scan_context ] revisits ranked first: " << first << "/" << places.size()
            << ", worst true-pair distance " << worst_true << "\n";
  EXPECT_GE(first, static_cast<int>(0.9 * places.size()));
  EXPECT_LT(worst_true, 0.6);
}

TEST(ScanContext, EmptyAndNonFiniteCloudsGiveAnEmptyDescriptor) {
  PointCloud cloud;
  PointT nan_point;
  nan_point.x = std::numeric_limits<float>::quiet_NaN();
  cloud.push_back(nan_point);
  const ScanContext sc = computeScanContext(cloud, ScanContextParams());
  EXPECT_EQ(sc.occupied_cells, 0);
  EXPECT_DOUBLE_EQ(matchScanContexts(sc, sc, ScanContextParams()).distance, 1.0);
}

TEST(DynamicKdIndex, MatchesBruteForceWithIndexLimit) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const int dim = 20;
  DynamicKdIndex index(dim);
  std::vector<std::vector<float>> data;
  for (int i = 0; i < 700; ++i) {
    std::vector<float> v(dim);
    for (auto& x : v) x = u(rng);
    data.push_back(v);
    ASSERT_TRUE(index.add(v.data()));
  }
  ASSERT_EQ(index.size(), 700u);
  for (int q = 0; q < 20; ++q) {
    std::vector<float> query(dim);
    for (auto& x : query) x = u(rng);
    const size_t limit = 100 + 30 * q;
    std::vector<std::pair<float, size_t>> brute;
    for (size_t i = 0; i < limit; ++i) {
      float d = 0.f;
      for (int k = 0; k < dim; ++k) d += (data[i][k] - query[k]) * (data[i][k] - query[k]);
      brute.push_back({d, i});
    }
    std::sort(brute.begin(), brute.end());
    const auto knn = index.knn(query.data(), 5, limit);
    ASSERT_EQ(knn.size(), 5u);
    for (size_t i = 0; i < 5; ++i) {
      EXPECT_EQ(knn[i].first, brute[i].second);
      EXPECT_NEAR(knn[i].second, brute[i].first, 1e-4);
    }
    const float radius = std::sqrt(brute[12].first) + 1e-4f;
    EXPECT_EQ(index.radius(query.data(), radius, limit).size(), 13u);
  }
}

}  // namespace
}  // namespace osm_graph_slam
