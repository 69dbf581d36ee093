// GraphBackend on synthetic drives with known truth: a street of buildings, a simulated LiDAR,
// the real wall/segment extraction, drifting odometry and perturbed OSM priors.
#include <gtest/gtest.h>

#include <random>

#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/lines/wall_scan_simulator.h"
#include "osm_graph_slam/slam/graph_backend.h"

using namespace osm_graph_slam;

namespace {

Eigen::Isometry3d se3(const Pose2& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(p.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.x, p.y, 0.0);
  return T;
}

Building toBuilding(int64_t id, const Polygon2& outline) {
  Building b;
  b.id = id;
  b.outline_enu = outline;
  size_t ref = 0;
  for (size_t i = 1; i < outline.size(); ++i)
    if (outline[i].x() < outline[ref].x()) ref = i;
  b.reference_pose = Pose2(outline[ref].x(), outline[ref].y(), 0.0);
  b.segments = polygonSegments(outline);
  return b;
}

/// A drive along a street with known truth. Keyframe segments come from simulated scans through
/// the production wall-point and segment extractors.
struct StreetDrive {
  std::vector<SimBuilding> scene;
  std::vector<Building> truth;
  std::vector<Pose2> true_poses;
  std::vector<std::vector<LineSegment2>> segments;

  explicit StreetDrive(int keyframes, double spacing = 2.5) {
    scene = makeStreetScene(16, 11);
    WallScanParams scan;
    scan.beams_per_ring = 900;
    const WallPointExtractor walls;
    const LineSegmentExtractor lines;
    for (int k = 0; k < keyframes; ++k) {
      // Gentle weave so that headings vary (otherwise every wall is parallel or orthogonal).
      const double x = -45.0 + spacing * k;
      const Pose2 pose(x, 0.8 * std::sin(0.05 * x), 0.04 * std::cos(0.05 * x));
      true_poses.push_back(pose);
      scan.seed = static_cast<uint32_t>(k + 1);
      const PointCloudPtr cloud = simulateWallScan(scene, pose, scan);
      segments.push_back(lines.extract(*walls.extract(*cloud)));
    }
    // The map origin is the first position (the first GPS fix), as in the back-end.
    const Pose2 shift(-true_poses[0].x, -true_poses[0].y, 0.0);
    for (auto& p : true_poses) p = shift * p;
    for (size_t i = 0; i < scene.size(); ++i) {
      truth.push_back(
          toBuilding(static_cast<int64_t>(1000 + i), transformPolygon(scene[i].outline, shift)));
    }
  }

  /// Odometry with a yaw bias and a scale error per step (drift), starting at the truth.
  std::vector<Eigen::Isometry3d> odometry(double yaw_bias_per_step, double scale) const {
    std::vector<Eigen::Isometry3d> odom = {se3(true_poses[0])};
    for (size_t k = 1; k < true_poses.size(); ++k) {
      Pose2 step = true_poses[k - 1].inverse() * true_poses[k];
      step = Pose2(step.x * scale, step.y * scale, step.theta + yaw_bias_per_step);
      odom.push_back(odom.back() * se3(step));
    }
    return odom;
  }

  /// Buildings moved: each by its own random offset (sigma) plus a common shift.
  std::vector<Building> perturbedPrior(double sigma_xy, double sigma_theta, const Pose2& common,
                                       uint32_t seed) const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    std::vector<Building> out;
    for (const auto& b : truth) {
      const Pose2 about = b.reference_pose;
      const Pose2 own(sigma_xy * n(rng), sigma_xy * n(rng), sigma_theta * n(rng));
      const Pose2 move = common * about * own * about.inverse();
      out.push_back(toBuilding(b.id, transformPolygon(b.outline_enu, move)));
    }
    return out;
  }

  Trajectory trueTrajectory() const {
    Trajectory t;
    for (size_t k = 0; k < true_poses.size(); ++k) t.push_back({0.1 * k, se3(true_poses[k])});
    return t;
  }

  void feed(GraphBackend& backend, const std::vector<Eigen::Isometry3d>& odom,
            const std::vector<Building>& prior) const {
    backend.addBuildings(prior, Eigen::Vector2d::Zero(), 1000.0);
    for (size_t k = 0; k < odom.size(); ++k) {
      KeyframeInput kf;
      kf.id = k;
      kf.stamp = 0.1 * k;
      kf.odom_pose = odom[k];
      kf.odom_fitness = 0.05;
      backend.addKeyframe(kf);
      backend.addLineSegments(k, segments[k]);
    }
  }
};

const StreetDrive& drive() {
  static const StreetDrive d(36);
  return d;
}

GraphBackendParams baseParams(OsmMode mode) {
  GraphBackendParams p;
  p.mode = mode;
  p.initial_yaw_known = true;
  p.initial_yaw = drive().true_poses[0].theta;
  return p;
}

double ate(const GraphBackend& backend) {
  return evaluateTrajectory(backend.trajectory(), drive().trueTrajectory()).ate.mean;
}

}  // namespace

TEST(GraphBackend, SimulatedKeyframesHaveWallSegments) {
  for (const auto& segs : drive().segments) EXPECT_GE(segs.size(), 4u);
}

TEST(GraphBackend, PriorModeCorrectsDriftingOdometryWithAnExactMap) {
  const auto odom = drive().odometry(0.004, 1.01);
  GraphBackendParams params = baseParams(OsmMode::kPrior);
  params.global_prior_std_xy = 0.05;  // the map is exact here: trust it
  params.global_prior_std_yaw = 0.005;
  GraphBackend backend(params);
  drive().feed(backend, odom, drive().truth);
  const BackendUpdateReport r = backend.update();
  EXPECT_EQ(r.keyframes_added, drive().true_poses.size());
  EXPECT_GT(r.global_priors, drive().true_poses.size() * 2 / 3);
  EXPECT_EQ(r.building_edges, 0u);  // buildings are fixed in prior mode

  Trajectory odom_traj;
  for (size_t k = 0; k < odom.size(); ++k) odom_traj.push_back({0.1 * k, odom[k]});
  const double odom_ate = evaluateTrajectory(odom_traj, drive().trueTrajectory()).ate.mean;
  EXPECT_GT(odom_ate, 0.8);
  EXPECT_LT(ate(backend), 0.10) << "odometry-only ATE " << odom_ate;
  std::cout << "prior mode: odometry ATE " << odom_ate << " m, SLAM ATE " << ate(backend) << " m\n";
  // Buildings untouched.
  const BuildingErrors b = evaluateBuildings(backend.correctedBuildings(), drive().truth);
  EXPECT_LT(b.max_corner_error, 1e-9);
}

TEST(GraphBackend, NonRigidModeCorrectsEachBuilding) {
  const auto odom = drive().odometry(0.0005, 1.001);
  const auto prior = drive().perturbedPrior(0.8, 0.03, Pose2(), 5);
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.global_prior_std_xy = 2.0;  // a noisy map: its global priors weigh little here
  params.global_prior_std_yaw = 0.05;
  GraphBackend backend(params);
  drive().feed(backend, odom, prior);
  const BackendUpdateReport r = backend.update();
  EXPECT_GT(r.building_edges, 50u);
  const BuildingErrors before = evaluateBuildings(prior, drive().truth);
  const BuildingErrors after = evaluateBuildings(backend.correctedBuildings(), drive().truth);
  EXPECT_GT(before.mean_corner_error, 0.6);
  EXPECT_LT(after.mean_corner_error, 0.5 * before.mean_corner_error)
      << "before " << before.mean_corner_error << " after " << after.mean_corner_error;
  EXPECT_LT(ate(backend), 0.2);
  std::cout << "non-rigid: building corner error " << before.mean_corner_error << " -> "
            << after.mean_corner_error << " m, ATE " << ate(backend) << " m\n";
}

TEST(GraphBackend, RigidModeRecoversACommonMapShift) {
  const auto odom = drive().odometry(0.0, 1.0);
  const Pose2 shift(0.9, -0.6, 0.01);
  const auto prior = drive().perturbedPrior(0.0, 0.0, shift, 5);
  GraphBackendParams params = baseParams(OsmMode::kRigid);
  params.global_prior_std_xy = 20.0;  // trust the (exact) odometry, move the map
  params.global_prior_std_yaw = 1.0;
  GraphBackend backend(params);
  drive().feed(backend, odom, prior);
  const BackendUpdateReport r = backend.update();
  EXPECT_GT(r.building_edges, 50u);
  const BuildingErrors before = evaluateBuildings(prior, drive().truth);
  const BuildingErrors after = evaluateBuildings(backend.correctedBuildings(), drive().truth);
  EXPECT_GT(before.mean_corner_error, 1.0);
  EXPECT_LT(after.mean_corner_error, 0.15) << "before " << before.mean_corner_error;
  EXPECT_LT(ate(backend), 0.05);
  std::cout << "rigid: building corner error " << before.mean_corner_error << " -> "
            << after.mean_corner_error << " m, ATE " << ate(backend) << " m\n";
}

TEST(GraphBackend, PhaseTwoMovesOnlyBuildings) {
  const auto odom = drive().odometry(0.002, 1.005);
  const auto prior = drive().perturbedPrior(0.8, 0.03, Pose2(), 9);
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.resolve_overlaps = false;
  // Reference: the same graph optimised at level 0 only (no building may influence robots).
  GraphBackendParams level0 = params;
  level0.mode = OsmMode::kPrior;  // same global priors, no building edges
  GraphBackend with_buildings(params), robots_only(level0);
  drive().feed(with_buildings, odom, prior);
  drive().feed(robots_only, odom, prior);
  with_buildings.update();
  robots_only.update();
  const auto a = with_buildings.trajectory(), b = robots_only.trajectory();
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k)
    EXPECT_LT((a[k].pose.translation() - b[k].pose.translation()).norm(), 1e-6) << k;
}

TEST(GraphBackend, OverlapResolutionSeparatesOnlyTheBuildingsInvolved) {
  const auto odom = drive().odometry(0.0, 1.0);
  std::vector<Building> prior = drive().truth;
  // Push building 3 along the street into its neighbour 4 by 2 m.
  double max3 = -1e9, min4 = 1e9;
  for (const auto& v : prior[3].outline_enu) max3 = std::max(max3, v.x());
  for (const auto& v : prior[4].outline_enu) min4 = std::min(min4, v.x());
  prior[3] = toBuilding(prior[3].id,
                        transformPolygon(prior[3].outline_enu, Pose2(min4 - max3 + 2.0, 0.0, 0.0)));
  ASSERT_EQ(findOverlappingBuildings(prior).size(), 1u);

  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.local_edge_std_xy = 100.0;  // isolate the overlap step: the scans barely move buildings
  params.local_edge_std_theta = 10.0;
  GraphBackend resolved(params);
  params.resolve_overlaps = false;
  GraphBackend unresolved(params);
  drive().feed(resolved, odom, prior);
  drive().feed(unresolved, odom, prior);
  const BackendUpdateReport r = resolved.update();
  unresolved.update();
  EXPECT_GE(r.overlap_edges, 1u);
  EXPECT_EQ(r.overlaps_remaining, 0u);
  const auto fixed = resolved.correctedBuildings();
  EXPECT_TRUE(findOverlappingBuildings(fixed).empty());
  const auto other = unresolved.correctedBuildings();
  ASSERT_EQ(fixed.size(), other.size());
  for (size_t i = 0; i < fixed.size(); ++i) {
    const double moved =
        (fixed[i].reference_pose.translation() - other[i].reference_pose.translation()).norm();
    if (fixed[i].id == prior[3].id || fixed[i].id == prior[4].id) continue;
    EXPECT_LT(moved, 1e-4) << "building " << fixed[i].id << " is not involved";
  }
}

TEST(GraphBackend, BadInputIsReportedAndKept) {
  std::vector<std::string> warnings;
  auto logger = std::make_shared<Logger>([&](LogLevel level, const std::string& msg) {
    if (level == LogLevel::kWarn) warnings.push_back(msg);
  });
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  GraphBackend backend(params, logger);
  // An update before any data is harmless.
  EXPECT_NO_THROW(backend.update(true));
  EXPECT_EQ(backend.numKeyframes(), 0u);
  EXPECT_TRUE(backend.correctedBuildings().empty());

  const auto odom = drive().odometry(0.0, 1.0);
  for (size_t k = 0; k < 10; ++k) {
    KeyframeInput kf;
    kf.id = k;
    kf.stamp = 0.1 * k;
    kf.odom_pose = odom[k];
    backend.addKeyframe(kf);  // no segments at all
  }
  LoopClosureInput loop;
  loop.from_id = 5;
  loop.to_id = 4242;  // unknown
  backend.addLoopClosure(loop);
  KeyframeInput dup;
  dup.id = 3;  // duplicate, arrives after 9
  BackendUpdateReport r = backend.update();
  backend.addKeyframe(dup);
  r = backend.update();
  EXPECT_EQ(backend.numKeyframes(), 10u);
  EXPECT_EQ(r.loops_rejected, 0u);  // reported in the first update
  bool saw_loop = false, saw_dup = false;
  for (const auto& w : warnings) {
    saw_loop |= w.find("unknown keyframe") != std::string::npos;
    saw_dup |= w.find("out of order") != std::string::npos;
  }
  EXPECT_TRUE(saw_loop);
  EXPECT_TRUE(saw_dup);

  // Buildings arriving late still get matched to the keyframes that waited for them.
  for (size_t k = 10; k < 20; ++k) {
    KeyframeInput kf;
    kf.id = k;
    kf.stamp = 0.1 * k;
    kf.odom_pose = odom[k];
    backend.addKeyframe(kf);
    backend.addLineSegments(k, drive().segments[k]);
  }
  r = backend.update();
  EXPECT_EQ(r.global_priors, 0u);  // no buildings yet
  backend.addBuildings(drive().truth, Eigen::Vector2d::Zero(), 1000.0);
  r = backend.update();
  EXPECT_GT(r.global_priors, 5u);
  EXPECT_GT(r.building_edges, 10u);
}
