// Registration back-ends: real KITTI pair against ground truth, synthetic exact recovery, and
// bad input (empty, NaN-only, single point) without exceptions.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "frontend_test_utils.h"
#include "osm_graph_slam/registration/registration.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

using test::rotationErrorDeg;
using test::translationError;

struct KittiPair {
  PointCloudPtr target, source;
  Eigen::Isometry3d truth;
};

KittiPair loadKittiPair() {
  KittiPair pair;
  pair.target = test::loadFilteredScan(test::sharedDataPath("kitti00/000094.bin"));
  pair.source = test::loadFilteredScan(test::sharedDataPath("kitti00/000095.bin"));
  pair.truth = test::readGroundTruthRelative(test::sharedDataPath("kitti00/gt_relative_lidar.txt"));
  return pair;
}

RegistrationResult alignKitti(const std::string& method, const KittiPair& pair) {
  RegistrationParams params;
  params.method = method;
  auto reg = createRegistration(params);
  reg->setTarget(pair.target);
  return reg->align(pair.source, Eigen::Isometry3d::Identity());
}

TEST(RegistrationTest, DefaultRecoversKittiMotionFromIdentity) {
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000095.bin"));
  const auto pair = loadKittiPair();
  ASSERT_GT(pair.source->size(), 1000u);
  // The ground truth moved 0.47 m: identity is a real initial error, not a head start.
  ASSERT_GT(pair.truth.translation().norm(), 0.4);
  const auto result = alignKitti(RegistrationParams().method, pair);
  ASSERT_TRUE(result.converged) << result.message;
  const double et = translationError(pair.truth, result.transform);
  const double er = rotationErrorDeg(pair.truth, result.transform);
  std::cout << "[kitti 94->95 fast_gicp] translation error " << et * 100 << " cm, rotation error "
            << er << " deg, fitness " << result.fitness << ", iterations " << result.iterations
            << ", " << result.time_ms << " ms\n";
  EXPECT_LT(et, 0.03);
  EXPECT_LT(er, 0.1);
  EXPECT_GT(result.iterations, 1);
  EXPECT_LT(result.fitness, 0.1);
}

TEST(RegistrationTest, VoxelizedGicpRecoversKittiMotionFromIdentity) {
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000095.bin"));
  const auto pair = loadKittiPair();
  const auto result = alignKitti("fast_vgicp", pair);
  ASSERT_TRUE(result.converged) << result.message;
  const double et = translationError(pair.truth, result.transform);
  const double er = rotationErrorDeg(pair.truth, result.transform);
  std::cout << "[kitti 94->95 fast_vgicp] translation error " << et * 100 << " cm, rotation error "
            << er << " deg, " << result.time_ms << " ms\n";
  EXPECT_LT(et, 0.03);
  EXPECT_LT(er, 0.1);
}

TEST(RegistrationTest, PclBaselinesRecoverKittiMotion) {
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000095.bin"));
  const auto pair = loadKittiPair();
  for (const std::string method : {"pcl_gicp", "pcl_ndt"}) {
    const auto result = alignKitti(method, pair);
    ASSERT_TRUE(result.converged) << method << ": " << result.message;
    const double et = translationError(pair.truth, result.transform);
    const double er = rotationErrorDeg(pair.truth, result.transform);
    std::cout << "[kitti 94->95 " << method << "] translation error " << et * 100
              << " cm, rotation error " << er << " deg, " << result.time_ms << " ms\n";
    EXPECT_LT(et, 0.10) << method;
    EXPECT_LT(er, 0.3) << method;
    EXPECT_GT(result.iterations, 0) << method;
  }
}

TEST(RegistrationTest, RecoversKnownSyntheticTransformExactly) {
  const auto target = test::syntheticScene();
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  truth.translation() << 0.6, -0.25, 0.08;
  truth.linear() = (Eigen::AngleAxisd(0.06, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
  // source = truth^-1 * target, so aligning source onto target must give truth.
  const auto source = test::transformed(*target, truth.inverse());
  RegistrationParams params;
  params.transformation_epsilon = 1e-6;
  auto reg = createRegistration(params);
  reg->setTarget(target);
  const auto result = reg->align(source, Eigen::Isometry3d::Identity());
  ASSERT_TRUE(result.converged) << result.message;
  const double et = translationError(truth, result.transform);
  const double er = rotationErrorDeg(truth, result.transform);
  std::cout << "[synthetic fast_gicp] translation error " << et * 1000 << " mm, rotation error "
            << er << " deg\n";
  EXPECT_LT(et, 0.001);
  EXPECT_LT(er, 0.01);
  EXPECT_LT(result.fitness, 1e-6);
}

// max_source_points: a bound at or above the source's size changes nothing (bit for bit); a
// bound below it aligns an evenly spread subset (covariances still from all source points) and
// lands within millimetres of the full alignment on the KITTI pair.
TEST(RegistrationTest, SourceSubsetStaysCloseToTheFullAlignment) {
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000095.bin"));
  const auto pair = loadKittiPair();
  auto run = [&](int max_source_points) {
    RegistrationParams params;
    params.num_threads = 1;  // the same summation order in every run
    params.max_source_points = max_source_points;
    auto reg = createRegistration(params);
    reg->setTarget(pair.target);
    return reg->align(pair.source, Eigen::Isometry3d::Identity());
  };
  const auto full = run(0);
  ASSERT_TRUE(full.converged) << full.message;
  const auto bounded_above = run(static_cast<int>(pair.source->size()));
  ASSERT_TRUE(bounded_above.converged);
  EXPECT_TRUE(bounded_above.transform.isApprox(full.transform, 0.0));
  EXPECT_EQ(bounded_above.fitness, full.fitness);
  const int subset = static_cast<int>(pair.source->size() / 3);
  const auto part = run(subset);
  ASSERT_TRUE(part.converged) << part.message;
  const double et = translationError(full.transform, part.transform);
  const double er = rotationErrorDeg(full.transform, part.transform);
  std::cout << "[kitti 94->95 fast_gicp, " << subset << " of " << pair.source->size()
            << " source points] " << et * 1000 << " mm, " << er << " deg from all points; "
            << translationError(pair.truth, part.transform) * 100 << " cm from the truth ("
            << translationError(pair.truth, full.transform) * 100 << " cm with all)\n";
  EXPECT_LT(et, 0.01);
  EXPECT_LT(er, 0.05);
  EXPECT_LT(translationError(pair.truth, part.transform), 0.03);
  EXPECT_NEAR(part.fitness, full.fitness, 0.2 * full.fitness);
}

// A recent target set again is reused (target_cache_size, the loop detector's candidate
// cache) with its lazily computed covariances: the same result as a fresh back-end, for both
// our methods and with more points matched the second time (a wider correspondence search).
TEST(RegistrationTest, RecentTargetsAreReusedWithTheSameResult) {
  const auto a = test::syntheticScene();
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  truth.translation() << 0.4, -0.2, 0.05;
  truth.linear() = Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto source = test::transformed(*a, truth.inverse());
  const auto b = test::transformed(*a, truth);
  for (const std::string method : {"fast_gicp", "fast_vgicp"}) {
    RegistrationParams params;
    params.method = method;
    params.num_threads = 1;  // the same summation order in every run
    auto fresh = createRegistration(params);
    fresh->setTarget(a);
    const auto expected = fresh->align(source, Eigen::Isometry3d::Identity());
    ASSERT_TRUE(expected.converged) << method << ": " << expected.message;
    params.target_cache_size = 2;
    auto cached = createRegistration(params);
    cached->setTarget(a);
    const auto first = cached->align(source, truth);  // a first use from another start
    cached->setTarget(b);
    cached->align(source, Eigen::Isometry3d::Identity());
    cached->setTarget(a);  // from the cache
    const auto again = cached->align(source, Eigen::Isometry3d::Identity());
    ASSERT_TRUE(first.converged && again.converged) << method;
    EXPECT_LT((again.transform.matrix() - expected.transform.matrix()).norm(), 1e-9) << method;
    EXPECT_NEAR(again.fitness, expected.fitness, 1e-12) << method;
    EXPECT_EQ(again.iterations, expected.iterations) << method;
    EXPECT_LT(translationError(truth, again.transform), 0.01) << method;
  }
}

/// Points on two walls at y = +-4 m along x in [-20, 20] and a floor at z = -1.7 m (a corridor),
/// with `cross_wall` a wall across it at x = 15 m; 2 mm noise.
PointCloudPtr corridor(bool cross_wall, unsigned seed) {
  std::srand(seed);
  auto noise = [] { return 0.002f * (2.0f * std::rand() / RAND_MAX - 1.0f); };
  PointCloudPtr cloud = std::make_shared<PointCloud>();
  auto add = [&](float x, float y, float z) {
    PointT p;
    p.getVector3fMap() = Eigen::Vector3f(x + noise(), y + noise(), z + noise());
    cloud->push_back(p);
  };
  for (float x = -20.0f; x <= 20.0f; x += 0.25f)
    for (float z = -1.5f; z <= 2.0f; z += 0.25f) {
      add(x, 4.0f, z);
      add(x, -4.0f, z);
    }
  for (float x = -20.0f; x <= 20.0f; x += 0.5f)
    for (float y = -3.75f; y <= 3.75f; y += 0.5f) add(x, y, -1.7f);
  if (cross_wall)
    for (float y = -3.75f; y <= 3.75f; y += 0.25f)
      for (float z = -1.5f; z <= 2.0f; z += 0.25f) add(15.0f, y, z);
  return cloud;
}

using Matrix6 = Eigen::Matrix<double, 6, 6>;

RegistrationResult alignCorridor(bool cross_wall) {
  RegistrationParams params;
  auto reg = createRegistration(params);
  reg->setTarget(corridor(cross_wall, 1));
  return reg->align(corridor(cross_wall, 2), Eigen::Isometry3d::Identity());
}

// The Hessian at the solution says what the scene constrains: in a corridor of two walls and a
// floor the translation along it is (almost) free; a wall across it constrains it.
TEST(RegistrationTest, HessianShowsWhatTheSceneConstrains) {
  const RegistrationResult open = alignCorridor(false), closed = alignCorridor(true);
  ASSERT_TRUE(open.converged) << open.message;
  ASSERT_TRUE(closed.converged) << closed.message;
  for (const auto* r : {&open, &closed}) {
    EXPECT_TRUE(r->hessian.isApprox(r->hessian.transpose(), 1e-9));
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6>(r->hessian).eigenvalues().minCoeff(), -1e-6);
  }
  const double along_open = open.hessian(0, 0), across_open = open.hessian(1, 1);
  std::printf(
      "[hessian] corridor: along %.3g, across %.3g, up %.3g; with a cross wall along %.3g\n",
      along_open, across_open, open.hessian(2, 2), closed.hessian(0, 0));
  EXPECT_LT(along_open, 0.01 * across_open);
  EXPECT_GT(closed.hessian(0, 0), 30.0 * along_open);
  EXPECT_GT(open.hessian(2, 2), 0.1 * across_open);  // the floor holds the height
}

TEST(RegistrationTest, PclBaselinesGiveNoHessian) {
  RegistrationParams params;
  params.method = "pcl_gicp";
  auto reg = createRegistration(params);
  reg->setTarget(corridor(true, 1));
  const RegistrationResult r = reg->align(corridor(true, 2), Eigen::Isometry3d::Identity());
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_TRUE(r.hessian.isZero()) << "zero means unknown to the back-end";
}

PointCloudPtr cloudOf(std::initializer_list<Eigen::Vector3f> points) {
  PointCloudPtr cloud = std::make_shared<PointCloud>();
  for (const auto& p : points) {
    PointT q;
    q.getVector3fMap() = p;
    cloud->push_back(q);
  }
  return cloud;
}

TEST(RegistrationTest, BadInputFailsCleanlyForEveryMethod) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const auto good = test::syntheticScene(300);
  const PointCloudPtr empty = std::make_shared<PointCloud>();
  const auto nan_only = cloudOf({{nan, nan, nan}, {nan, 1, 2}, {3, nan, 1}});
  const auto single = cloudOf({{1, 2, 3}});
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  guess.translation() << 0.3, 0.2, 0.1;
  for (const std::string method : {"fast_gicp", "fast_vgicp", "pcl_gicp", "pcl_ndt"}) {
    RegistrationParams params;
    params.method = method;
    for (const auto& bad : {empty, nan_only, single, PointCloudPtr()}) {
      auto reg = createRegistration(params);
      // Bad source against a good target, and a good source against a bad target.
      reg->setTarget(good);
      RegistrationResult r1, r2;
      ASSERT_NO_THROW(r1 = reg->align(bad, guess)) << method;
      EXPECT_FALSE(r1.converged) << method;
      EXPECT_FALSE(r1.message.empty()) << method;
      EXPECT_TRUE(r1.transform.isApprox(guess)) << method;
      ASSERT_NO_THROW(reg->setTarget(bad)) << method;
      ASSERT_NO_THROW(r2 = reg->align(good, guess)) << method;
      EXPECT_FALSE(r2.converged) << method;
      EXPECT_FALSE(r2.message.empty()) << method;
      EXPECT_TRUE(r2.transform.isApprox(guess)) << method;
    }
  }
}

TEST(RegistrationTest, UnknownMethodThrows) {
  RegistrationParams params;
  params.method = "icp_of_dreams";
  EXPECT_THROW(createRegistration(params), std::invalid_argument);
}

}  // namespace
}  // namespace osm_graph_slam
