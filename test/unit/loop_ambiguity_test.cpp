// The correlative (bird's-eye-view) verification stage of loop detection: it finds the true pose
// of a re-scan anywhere in the odometry tolerance window (also between identical facades), it
// reports a corridor whose walls constrain only one direction as ambiguous, the detector rejects
// such a match (and accepts it, wrongly placed, when the test is disabled), and it corrects the
// wrong loop that the coarse GICP stage accepted in loop_benchmark at 5,000 keyframes (a
// registration local minimum 4 m from the truth).
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <stdexcept>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/loop/bev_correlation.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/sim/synthetic_world.h"

namespace osm_graph_slam {
namespace {

constexpr double kPeriod = 10.0;  // [m] of the identical-facade street

/// A straight street along x lined on both sides by identical buildings every kPeriod metres
/// and nothing else: every placement shifted by a period looks the same.
SyntheticWorld periodicStreet() {
  SyntheticWorld world;
  for (int k = -30; k <= 30; ++k) {
    for (double side : {-12.0, 12.0}) {
      SyntheticBox box;
      box.center = Eigen::Vector2d(k * kPeriod, side);
      box.half_size = Eigen::Vector2d(3.0, 4.0);
      box.height = 8.0;
      world.boxes.push_back(box);
    }
  }
  return world;
}

/// Two continuous walls 16 m apart along x and nothing else: the along-track position is not
/// observable (a tunnel, a road between noise barriers).
SyntheticWorld corridor() {
  SyntheticWorld world;
  for (double side : {-10.0, 10.0}) {
    SyntheticBox wall;
    wall.center = Eigen::Vector2d(0.0, side);
    wall.half_size = Eigen::Vector2d(300.0, 2.0);
    wall.height = 8.0;
    world.boxes.push_back(wall);
  }
  return world;
}

PointCloudPtr scanAt(const SyntheticWorld& world, double x, double y, double yaw, uint32_t seed) {
  return simulateSyntheticScan(world, Eigen::Vector2d(x, y), yaw, SyntheticLidarParams(), seed);
}

Eigen::Vector3d planar(const Eigen::Isometry3d& pose) {
  return {pose.translation().x(), pose.translation().y(),
          std::atan2(pose.linear()(1, 0), pose.linear()(0, 0))};
}

double translationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}

double rotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd((a.inverse() * b).linear()).angle() * 180.0 / M_PI;
}

TEST(BevCorrelation, FindsTheTruePoseOfARescanInTheWholeWindow) {
  const SyntheticWorld town = makeLoopTown(200.0, 120.0, 14.0, 7);
  // A place on the second street (random buildings, poles, cars), re-scanned 1 m / 0.5 m /
  // 0.2 rad away; the window is centred 1.8 m and 0.04 rad off the truth.
  const Eigen::Isometry3d place = isometryFromPlanar(Pose2(200.0, 60.0, M_PI / 2));
  const Eigen::Isometry3d truth = isometryFromPlanar(Pose2(1.0, 0.5, 0.2));
  const Eigen::Vector3d again = planar(place * truth);
  BevCorrelationParams params;
  const BevLikelihoodField field(*downsampleForLoop(*scanAt(town, 200.0, 60.0, M_PI / 2, 1), 0.6),
                                 params);
  const auto points = bevQueryPoints(
      *downsampleForLoop(*scanAt(town, again.x(), again.y(), again.z(), 2), 0.6), params);
  ASSERT_FALSE(field.empty());
  ASSERT_GT(points.size(), 100u);
  BevSearchWindow window;
  window.center = Eigen::Vector3d(1.0 + 1.5, 0.5 - 1.0, 0.2 + 0.04);
  window.translation_radius = 3.0;
  window.yaw_radius = 0.1;
  const BevSearchResult r = searchBev(field, points, window, params);
  ASSERT_TRUE(r.valid);
  std::cout << "[ bev ] best (" << r.best.transpose() << ") score " << r.best_score
            << ", runner-up (" << r.runner_up.transpose() << ") " << r.runner_up_score
            << ", ambiguity " << r.ambiguity() << ", " << r.poses << " poses, " << r.query_points
            << " points\n";
  // Lattice: 0.5 m cells, 2 deg yaw steps -> within one cell and one step.
  EXPECT_LT((r.best.head<2>() - Eigen::Vector2d(1.0, 0.5)).norm(), 0.5);
  EXPECT_LT(std::abs(r.best.z() - 0.2), 0.036);
  EXPECT_GT(r.best_score, 0.6);
  EXPECT_LT(r.ambiguity(), 0.8) << "a street of distinct buildings is not ambiguous";
  EXPECT_GT(r.poses, 100);
  // Empty target or query: no result, no crash.
  EXPECT_FALSE(searchBev(BevLikelihoodField(PointCloud(), params), points, window, params).valid);
  EXPECT_FALSE(searchBev(field, {}, window, params).valid);
}

TEST(BevCorrelation, IdenticalFacadesStillPickTheTruePlacement) {
  // Both the true placement and its alias one period ahead are in the window. The alias is not
  // a perfect copy: the side walls seen near the sensor depend on where it stands within the
  // period, so the whole-window search prefers the truth and the alias is only the runner-up.
  const SyntheticWorld street = periodicStreet();
  BevCorrelationParams params;
  const BevLikelihoodField field(*downsampleForLoop(*scanAt(street, 0.0, 0.0, 0.0, 1), 0.6),
                                 params);
  const auto points =
      bevQueryPoints(*downsampleForLoop(*scanAt(street, 0.3, 0.5, 0.0, 2), 0.6), params);
  BevSearchWindow wide;
  wide.center = Eigen::Vector3d(0.3 + kPeriod / 2, 0.5, 0.0);
  wide.translation_radius = 7.0;
  wide.yaw_radius = 0.05;
  const BevSearchResult a = searchBev(field, points, wide, params);
  ASSERT_TRUE(a.valid);
  ASSERT_TRUE(a.valid_runner_up);
  std::cout << "[ bev periodic ] best (" << a.best.transpose() << ") " << a.best_score
            << ", runner-up (" << a.runner_up.transpose() << ") " << a.runner_up_score
            << ", ambiguity " << a.ambiguity() << "\n";
  EXPECT_LT((a.best.head<2>() - Eigen::Vector2d(0.3, 0.5)).norm(), 0.5);
  EXPECT_NEAR(a.runner_up.x() - a.best.x(), kPeriod, 1.0) << "the alias is a period ahead";
  EXPECT_LT(std::abs(a.runner_up.y() - a.best.y()), 0.6);
  EXPECT_GT(a.ambiguity(), 0.6) << "the alias fits well";  // measured 0.79
  EXPECT_LT(a.ambiguity(), 0.85) << "but clearly worse";   // default max_ambiguity 0.9
  // A window that holds one period only.
  BevSearchWindow narrow = wide;
  narrow.center = Eigen::Vector3d(0.3 + 1.5, 0.5, 0.0);
  narrow.translation_radius = 3.0;
  const BevSearchResult b = searchBev(field, points, narrow, params);
  ASSERT_TRUE(b.valid);
  EXPECT_LT((b.best.head<2>() - Eigen::Vector2d(0.3, 0.5)).norm(), 0.5);
  EXPECT_LT(b.ambiguity(), 0.6);  // measured 0.38
}

TEST(BevCorrelation, ACorridorIsAmbiguousAlongItsAxis) {
  const SyntheticWorld walls = corridor();
  BevCorrelationParams params;
  const BevLikelihoodField field(*downsampleForLoop(*scanAt(walls, 0.0, 0.0, 0.0, 1), 0.6), params);
  const auto points =
      bevQueryPoints(*downsampleForLoop(*scanAt(walls, 0.3, 0.5, 0.0, 2), 0.6), params);
  BevSearchWindow window;
  window.center = Eigen::Vector3d(2.0, 0.5, 0.0);
  window.translation_radius = 3.0;
  window.yaw_radius = 0.05;
  const BevSearchResult r = searchBev(field, points, window, params);
  ASSERT_TRUE(r.valid);
  ASSERT_TRUE(r.valid_runner_up);
  std::cout << "[ bev corridor ] best (" << r.best.transpose() << ") " << r.best_score
            << ", runner-up (" << r.runner_up.transpose() << ") " << r.runner_up_score
            << ", ambiguity " << r.ambiguity() << "\n";
  EXPECT_GT(r.ambiguity(), 0.95);
  // Lateral position and heading are observable: both placements agree on them.
  EXPECT_LT(std::abs(r.best.y() - 0.5), 0.5);
  EXPECT_LT(std::abs(r.runner_up.y() - 0.5), 0.5);
  EXPECT_GE(std::abs(r.runner_up.x() - r.best.x()), params.peak_separation - 1e-9);
}

/// A one-keyframe database in the corridor and a query 0.3 m further on whose odometry is 2.7 m
/// ahead of it (tolerance 2 m + 1 % of 300 m = 5 m).
struct CorridorCase {
  LoopKeyframe stored, query;
};

CorridorCase corridorCase() {
  const SyntheticWorld walls = corridor();
  CorridorCase c;
  c.stored.id = 0;
  c.stored.accum_distance = 0.0;
  c.stored.cloud = scanAt(walls, 0.0, 0.0, 0.0, 1);
  c.query.id = 1;
  c.query.accum_distance = 300.0;
  c.query.odom_pose = isometryFromPlanar(Pose2(3.0, 0.5, 0.0));
  c.query.cloud = scanAt(walls, 0.3, 0.5, 0.0, 2);
  return c;
}

TEST(LoopDetector, RejectsAnAmbiguousMatchInACorridor) {
  const CorridorCase c = corridorCase();
  LoopDetector detector{LoopDetectorParams()};
  ASSERT_TRUE(detector.addKeyframe(c.stored));
  EXPECT_FALSE(detector.detect(c.query).has_value());
  const LoopQueryStats& s = detector.lastStats();
  EXPECT_GE(s.rejected_ambiguous, 1);
  ASSERT_FALSE(s.outcomes.empty());
  EXPECT_EQ(s.outcomes.front().verdict, "ambiguous");
  EXPECT_GT(s.outcomes.front().ambiguity, 0.95);
  EXPECT_EQ(s.fine_registrations, 0) << "rejected before the fine stage";
}

TEST(LoopDetector, WithoutTheAmbiguityTestTheSameMatchIsAccepted) {
  // The rejection above is the ambiguity test's doing: the registration fits wherever it lands
  // along the corridor, so fitness, overlap and odometry all pass, and the loop's along-track
  // position is whatever the seed was, not the truth.
  const CorridorCase c = corridorCase();
  LoopDetectorParams params;
  params.max_ambiguity = 1.01;
  LoopDetector detector(params);
  ASSERT_TRUE(detector.addKeyframe(c.stored));
  const auto loop = detector.detect(c.query);
  ASSERT_TRUE(loop.has_value()) << detector.lastStats().reason;
  EXPECT_LT(loop->fitness, params.max_fitness);
  EXPECT_GT(loop->overlap, params.min_overlap);
  const Eigen::Vector3d t = loop->relative_pose.translation();
  std::cout << "[ corridor, no ambiguity test ] accepted at (" << t.transpose()
            << "), truth (0.3 0.5 0), fitness " << loop->fitness << ", overlap " << loop->overlap
            << "\n";
  EXPECT_LT(std::abs(t.y() - 0.5), 0.1) << "the lateral position is observable";
}

/// The wrong loop of loop_benchmark at 5,000 keyframes: the query re-scans town place 17 (85 m
/// down the facade street) 1 m / 0.5 m / 0.2 rad away; two database keyframes 2 m apart in
/// odometry hold the scans of places 17 and 18, 5 m apart in the town. The query's odometry is
/// nearer to the keyframe of place 18, whose true relative pose is (-4, 0.5, 0.2): 3.1 m from
/// the odometry, inside the 4 m tolerance. The coarse GICP stage settled at (0.02, 0.5) there
/// (a local minimum between facades and poles, fitness 0.17, overlap 0.50) and was accepted.
struct BenchmarkCase {
  LoopKeyframe place17, place18, query;
  Eigen::Isometry3d truth_in_18;
};

BenchmarkCase benchmarkCase() {
  const SyntheticWorld town = makeLoopTown(200.0, 120.0, 14.0, 7);
  const auto places = loopTownRoute(200.0, 120.0, 0.0, 5.0, 0.0, 0.0);
  auto poolScan = [&](int i) {
    return downsampleForLoop(*scanAt(town, places[i].x(), places[i].y(), places[i].z(), 1), 0.4);
  };
  const Eigen::Isometry3d offset = isometryFromPlanar(Pose2(1.0, 0.5, 0.2));
  const Eigen::Isometry3d at17 = isometryFromPlanar(Pose2(places[17].x(), places[17].y(), 0.0));
  const Eigen::Isometry3d at18 = isometryFromPlanar(Pose2(places[18].x(), places[18].y(), 0.0));
  const Eigen::Vector3d again = planar(at17 * offset);
  BenchmarkCase c;
  c.place17.id = 0;
  c.place17.accum_distance = 0.0;
  c.place17.cloud = poolScan(17);
  c.place18.id = 1;
  c.place18.odom_pose = isometryFromPlanar(Pose2(2.0, 0.0, 0.0));
  c.place18.accum_distance = 2.0;
  c.place18.cloud = poolScan(18);
  c.query.id = 2;
  c.query.odom_pose = isometryFromPlanar(Pose2(1.1, 0.5, 0.2));
  c.query.accum_distance = 202.0;
  c.query.cloud = scanAt(town, again.x(), again.y(), again.z(), 1017);
  c.truth_in_18 = at18.inverse() * at17 * offset;
  return c;
}

TEST(LoopDetector, CorrectsTheBenchmarkLocalMinimum) {
  const BenchmarkCase c = benchmarkCase();
  EXPECT_NEAR(c.truth_in_18.translation().x(), -4.0, 1e-6);
  for (const std::string coarse : {"gicp", "correlative"}) {
    LoopDetectorParams params;
    params.coarse_method = coarse;
    LoopDetector detector(params);
    ASSERT_TRUE(detector.addKeyframe(c.place17));
    ASSERT_TRUE(detector.addKeyframe(c.place18));
    const auto loop = detector.detect(c.query);
    const auto& s = detector.lastStats();
    ASSERT_FALSE(s.outcomes.empty());
    EXPECT_EQ(s.outcomes.front().id, 1u) << "the keyframe nearest to the odometry comes first";
    if (coarse == "gicp") {
      // The trap, as measured with the previous pipeline (informative: a better registration
      // back-end may escape it).
      if (loop) {
        std::cout << "[ benchmark case, coarse gicp ] loop to " << loop->to_id << " error "
                  << (loop->to_id == 1 ? translationError(c.truth_in_18, loop->relative_pose)
                                       : -1.0)
                  << " m, fitness " << loop->fitness << ", overlap " << loop->overlap << "\n";
      }
      continue;
    }
    ASSERT_TRUE(loop.has_value()) << s.reason;
    std::cout << "[ benchmark case, correlative ] loop to " << loop->to_id << ", ambiguity "
              << s.outcomes.back().ambiguity << ", fitness " << loop->fitness << ", overlap "
              << loop->overlap << "\n";
    ASSERT_EQ(loop->to_id, 1u);
    EXPECT_LT(translationError(c.truth_in_18, loop->relative_pose), 0.10);
    EXPECT_LT(rotationErrorDeg(c.truth_in_18, loop->relative_pose), 0.5);
    EXPECT_LT(s.outcomes.back().ambiguity, LoopDetectorParams().max_ambiguity);
  }
}

TEST(LoopDetector, FineStageThatLeavesTheCorrelativePeakIsRejected) {
  // With no allowed shift every fine result (off the 0.5 m lattice) counts as having left the
  // peak: the check is wired between the fine stage and acceptance.
  const BenchmarkCase c = benchmarkCase();
  LoopDetectorParams params;
  params.max_refinement_shift = 0.0;
  LoopDetector detector(params);
  ASSERT_TRUE(detector.addKeyframe(c.place17));
  ASSERT_TRUE(detector.addKeyframe(c.place18));
  EXPECT_FALSE(detector.detect(c.query).has_value());
  EXPECT_GE(detector.lastStats().rejected_refinement, 1);
}

TEST(LoopDetector, UnknownCoarseMethodIsRefused) {
  LoopDetectorParams params;
  params.coarse_method = "branch_and_bound";
  EXPECT_THROW(LoopDetector{params}, std::invalid_argument);
}

}  // namespace
}  // namespace osm_graph_slam
