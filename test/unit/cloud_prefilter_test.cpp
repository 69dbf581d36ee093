// CloudPrefilter: each step on controlled input, octant-parallel outlier removal equal to the
// whole-cloud result on a real scan, bad input without exceptions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <tuple>

#include <pcl/filters/voxel_grid.h>
#include "frontend_test_utils.h"

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/cloud/voxel_filter.h"
#include "osm_graph_slam/common/memory_tuning.h"
#include "test_data.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace osm_graph_slam {
namespace {

PointT pointAt(float x, float y, float z) {
  PointT p;
  p.x = x;
  p.y = y;
  p.z = z;
  p.intensity = 0.5f;
  return p;
}

CloudPrefilterParams onlyBasicSteps() {
  CloudPrefilterParams params;
  params.use_voxel_grid = false;
  params.use_outlier_removal = false;
  return params;
}

std::vector<std::tuple<float, float, float>> sortedPoints(const PointCloud& cloud) {
  std::vector<std::tuple<float, float, float>> out;
  for (const auto& p : cloud.points) out.emplace_back(p.x, p.y, p.z);
  std::sort(out.begin(), out.end());
  return out;
}

TEST(CloudPrefilterTest, EmptyNanOnlyAndSinglePointGiveEmptyResultWithReason) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  CloudPrefilter prefilter;
  PointCloud empty;
  PointCloud nan_only;
  nan_only.push_back(pointAt(nan, nan, nan));
  nan_only.push_back(pointAt(inf, 1, 2));
  PointCloud single;
  single.push_back(pointAt(10, 0, 0));
  for (const PointCloud* input : {&empty, &nan_only, &single}) {
    CloudPrefilterResult result;
    ASSERT_NO_THROW(result = prefilter.filter(*input));
    ASSERT_TRUE(result.cloud);
    EXPECT_TRUE(result.cloud->empty());
    EXPECT_FALSE(result.ok);
    EXPECT_FALSE(result.reason.empty());
  }
  EXPECT_NE(prefilter.filter(nan_only).reason.find("NaN"), std::string::npos);
}

TEST(CloudPrefilterTest, RemovesInvalidPointsAndCropsRange) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointCloud input;
  input.push_back(pointAt(1.0f, 0, 0));    // too close (min 2 m)
  input.push_back(pointAt(5.0f, 0, 0));    // kept
  input.push_back(pointAt(0, -50.0f, 3));  // kept
  input.push_back(pointAt(120.0f, 0, 0));  // too far (max 100 m)
  input.push_back(pointAt(nan, 2.0f, 0));  // invalid
  const auto result = CloudPrefilter(onlyBasicSteps()).filter(input);
  ASSERT_TRUE(result.ok) << result.reason;
  ASSERT_EQ(result.cloud->size(), 2u);
  EXPECT_EQ(result.stats.after_invalid, 4u);
  EXPECT_EQ(result.stats.after_crop, 2u);
  EXPECT_FLOAT_EQ(result.cloud->points[0].x, 5.0f);
  EXPECT_FLOAT_EQ(result.cloud->points[1].y, -50.0f);
  EXPECT_TRUE(result.cloud->is_dense);
}

TEST(CloudPrefilterTest, DisabledStepsPassPointsThrough) {
  PointCloud input;
  input.push_back(pointAt(1.0f, 0, 0));
  input.push_back(pointAt(500.0f, 0, 0));
  auto params = onlyBasicSteps();
  params.use_range_crop = false;
  const auto result = CloudPrefilter(params).filter(input);
  EXPECT_EQ(result.cloud->size(), 2u);
}

TEST(CloudPrefilterTest, AppliesSensorToBaseTransform) {
  PointCloud input;
  input.push_back(pointAt(10, 0, 0));
  auto params = onlyBasicSteps();
  params.sensor_to_base.translation() << 1.0, 2.0, 3.0;
  params.sensor_to_base.linear() =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto result = CloudPrefilter(params).filter(input);
  ASSERT_EQ(result.cloud->size(), 1u);
  EXPECT_NEAR(result.cloud->points[0].x, 1.0, 1e-5);
  EXPECT_NEAR(result.cloud->points[0].y, 12.0, 1e-5);
  EXPECT_NEAR(result.cloud->points[0].z, 3.0, 1e-5);
}

TEST(CloudPrefilterTest, VoxelGridKeepsOnePointPerCell) {
  PointCloud input;
  for (int i = 0; i < 10; ++i) input.push_back(pointAt(10.0f + 0.01f * i, 0.1f, 0.1f));
  for (int i = 0; i < 10; ++i) input.push_back(pointAt(20.0f + 0.01f * i, 0.1f, 0.1f));
  for (const std::string method : {"approximate", "exact"}) {
    auto params = onlyBasicSteps();
    params.use_voxel_grid = true;
    params.voxel_method = method;
    const auto result = CloudPrefilter(params).filter(input);
    EXPECT_EQ(result.cloud->size(), 2u) << method;
  }
}

TEST(CloudPrefilterTest, RadiusOutlierRemovalDropsIsolatedPoints) {
  PointCloud input;
  // A dense 3 x 3 x 3 block of points 0.2 m apart and one point 20 m away from everything.
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) input.push_back(pointAt(10 + 0.2f * i, 0.2f * j, 0.2f * k));
  input.push_back(pointAt(-10, 15, 0));
  for (const std::string backend : {"grid", "pcl"})
    for (const bool octants : {false, true}) {
      auto params = onlyBasicSteps();
      params.use_outlier_removal = true;
      params.radius_backend = backend;
      params.parallel_octants = octants;
      const auto result = CloudPrefilter(params).filter(input);
      EXPECT_EQ(result.cloud->size(), 27u) << backend << " octants=" << octants;
    }
}

TEST(CloudPrefilterTest, GridRadiusRemovalKeepsExactlyThePclPoints) {
  // Border cases first: a neighbour just inside and just outside the radius, a duplicate point,
  // points on cell borders and negative coordinates.
  PointCloud edge;
  for (const float x : {-1.0f, 0.0f, 0.999f, 2.0f, 3.0f, 3.0f, -5.5f, -4.5001f, 7.0f, 8.0001f})
    edge.push_back(pointAt(x, -0.5f, 0.25f));
  for (const int min_neighbors : {1, 2}) {
    CloudPrefilterParams params = onlyBasicSteps();
    params.use_outlier_removal = true;
    params.radius_min_neighbors = min_neighbors;
    params.radius_backend = "pcl";
    const auto pcl_kept = CloudPrefilter(params).removeOutliers(edge.makeShared(), false);
    params.radius_backend = "grid";
    const auto grid_kept = CloudPrefilter(params).removeOutliers(edge.makeShared(), false);
    EXPECT_EQ(sortedPoints(*pcl_kept), sortedPoints(*grid_kept)) << min_neighbors;
  }
  const auto path = test::sharedDataPath("kitti00/000094.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  const auto raw = test::loadScan(path);
  CloudPrefilterParams params;
  params.use_outlier_removal = false;
  const auto voxelized = CloudPrefilter(params).filter(*raw).cloud;
  params.use_outlier_removal = true;
  for (const double radius : {0.5, 1.0, 1.5})
    for (const bool octants : {false, true}) {
      params.radius_search = radius;
      params.radius_backend = "pcl";
      const auto reference = CloudPrefilter(params).removeOutliers(voxelized, octants);
      params.radius_backend = "grid";
      const auto grid = CloudPrefilter(params).removeOutliers(voxelized, octants);
      std::cout << "[radius " << radius << (octants ? ", octants" : ", whole") << "] "
                << voxelized->size() << " -> pcl " << reference->size() << ", grid " << grid->size()
                << "\n";
      EXPECT_LT(reference->size(), voxelized->size()) << radius << ": nothing was removed";
      // Same points in the same order (input order, or octant by octant as PCL's octants):
      // the keyframe clouds' order steers the RANSAC of walls and floors downstream.
      ASSERT_EQ(reference->size(), grid->size()) << radius;
      for (size_t i = 0; i < reference->size(); ++i)
        ASSERT_EQ(reference->points[i].getVector3fMap(), grid->points[i].getVector3fMap()) << i;
    }
  params.radius_backend = "octree";
  EXPECT_THROW(CloudPrefilter{params}, std::invalid_argument);
}

TEST(CloudPrefilterTest, OctantOutlierRemovalEqualsWholeCloudOnRealScan) {
  const auto path = test::sharedDataPath("kitti00/000094.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  const auto raw = test::loadScan(path);
  for (const std::string method : {"radius", "statistical"}) {
    CloudPrefilterParams params;
    params.outlier_method = method;
    params.radius_backend = "pcl";  // the octant split is PCL's
    params.use_outlier_removal = false;
    const auto voxelized = CloudPrefilter(params).filter(*raw).cloud;
    params.use_outlier_removal = true;
    CloudPrefilter prefilter(params);
    const auto whole = prefilter.removeOutliers(voxelized, false);
    const auto octants = prefilter.removeOutliers(voxelized, true);
    std::cout << "[" << method << "] " << voxelized->size() << " -> whole " << whole->size()
              << ", octants " << octants->size() << "\n";
    EXPECT_LT(whole->size(), voxelized->size()) << method << ": nothing was removed";
    if (method == "radius") {
      // With a margin of one search radius every border point sees its full neighbourhood.
      EXPECT_EQ(sortedPoints(*whole), sortedPoints(*octants));
    } else {
      // Statistics are per octant: nearly, not exactly, the same points.
      const double diff = std::abs(double(whole->size()) - double(octants->size()));
      EXPECT_LT(diff / whole->size(), 0.01);
    }
  }
}

// voxelCentroids (loop detection's filter) is pcl::VoxelGrid without its per-field copies: the
// same voxels in the same order, centroids equal up to the float sums' order.
TEST(VoxelCentroidsTest, EqualsPclVoxelGridOnRealScan) {
  const auto path = test::sharedDataPath("kitti00/000094.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  const auto raw = test::loadScan(path);
  auto input = std::make_shared<PointCloud>(*raw);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = 0; i < input->size(); i += 97) input->points[i].y = nan;
  auto finite = std::make_shared<PointCloud>();
  for (const auto& p : input->points)
    if (std::isfinite(p.y)) finite->push_back(p);
  for (const double leaf : {0.2, 0.6, 1.5}) {
    PointCloud expected;
    pcl::VoxelGrid<PointT> grid;
    grid.setLeafSize(float(leaf), float(leaf), float(leaf));
    grid.setInputCloud(finite);
    grid.filter(expected);
    const auto result = voxelCentroids(*input, leaf);
    ASSERT_EQ(result->size(), expected.size()) << leaf;
    double worst = 0.0;
    for (size_t i = 0; i < expected.size(); ++i) {
      worst = std::max<double>(
          worst, (result->points[i].getVector3fMap() - expected.points[i].getVector3fMap()).norm());
      ASSERT_NEAR(result->points[i].intensity, expected.points[i].intensity, 1e-4) << i;
    }
    EXPECT_LT(worst, 1e-4) << leaf;
    EXPECT_TRUE(result->is_dense);
    EXPECT_EQ(result->width, result->size());
  }
}

TEST(VoxelCentroidsTest, EmptyNanOnlyAndFarPoints) {
  PointCloud cloud;
  EXPECT_TRUE(voxelCentroids(cloud, 0.5)->empty());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud.push_back(pointAt(nan, 1.f, 1.f));
  cloud.push_back(pointAt(1.f, std::numeric_limits<float>::infinity(), 1.f));
  EXPECT_TRUE(voxelCentroids(cloud, 0.5)->empty());
  // Beyond 2^20 voxels from the origin: PCL's filter takes over.
  cloud.push_back(pointAt(0.1f, 0.1f, 0.1f));
  cloud.push_back(pointAt(0.2f, 0.2f, 0.2f));
  cloud.push_back(pointAt(3.0e5f, 0.f, 0.f));
  const auto far = sortedPoints(*voxelCentroids(cloud, 0.1));
  ASSERT_EQ(far.size(), 3u);
  EXPECT_FLOAT_EQ(std::get<0>(far[0]), 0.1f);
  EXPECT_FLOAT_EQ(std::get<0>(far[2]), 3.0e5f);
  // Two points in one voxel: their mean.
  const auto near = voxelCentroids(cloud, 1.0);
  ASSERT_EQ(near->size(), 1u + 1u);
  EXPECT_FLOAT_EQ(near->points[0].x, 0.15f);
}

TEST(CloudPrefilterTest, RealScanIsReducedAndStaysInRange) {
  const auto path = test::sharedDataPath("kitti00/000094.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  const auto raw = test::loadScan(path);
  CloudPrefilterParams params;
  const auto result = CloudPrefilter(params).filter(*raw);
  ASSERT_TRUE(result.ok) << result.reason;
  std::cout << "[prefilter] " << raw->size() << " -> " << result.cloud->size() << " points in "
            << result.stats.time_total_ms << " ms\n";
  EXPECT_GT(result.cloud->size(), 5000u);
  EXPECT_LT(result.cloud->size(), raw->size() / 4);
  for (const auto& p : result.cloud->points) {
    // Approximate voxel centroids stay within one leaf of the crop limits.
    const double r = p.getVector3fMap().norm();
    ASSERT_GT(r, params.min_range - params.voxel_leaf_size);
    ASSERT_LT(r, params.max_range + params.voxel_leaf_size);
  }
}

// reuseFreedMemory() did nothing for two sessions: its #if tested __GLIBC__ before any libc
// header had defined it. A scan-sized block must now come from the heap, not a fresh mapping
// (glibc's default threshold maps anything above 128 KiB at first).
TEST(MemoryTuning, ScanSizedBlocksComeFromTheHeapNotFreshMappings) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's allocator replaces glibc's: mallopt does not apply";
#elif defined(__GLIBC__)
  ASSERT_TRUE(reuseFreedMemory());
  const size_t mapped_before = mallinfo2().hblkhd;
  void* block = std::malloc(8 * 1024 * 1024);
  ASSERT_NE(block, nullptr);
  EXPECT_EQ(mallinfo2().hblkhd, mapped_before);
  std::free(block);
#else
  GTEST_SKIP() << "allocator tuning is glibc-only";
#endif
}

}  // namespace
}  // namespace osm_graph_slam
