// GraphBackend on synthetic drives with known truth: a street of buildings, a simulated LiDAR,
// the real wall/segment extraction, drifting odometry and perturbed OSM priors.
#include <algorithm>
#include <cstdio>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "backend_test_utils.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/common/sequence_gaps.h"
#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/graph/information.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/optimization_schedule.h"
#include "street_drive.h"

using namespace osm_graph_slam;

namespace {

using test::StreetDrive;
using test::toBuilding;

const StreetDrive& drive() {
  static const StreetDrive d(36);
  return d;
}

GraphBackendParams baseParams(OsmMode mode) {
  GraphBackendParams p;
  p.mode = mode;
  p.initial_yaw_known = true;
  p.initial_yaw = drive().true_poses[0].theta;
  // The drives below drift by up to 4 mrad of yaw and 1 % of length per keyframe, ten times worse
  // than scan matching on the simulated KITTI drives: the odometry edges say so.
  p.odometry.information.max_std_rot =
      0.02;  // and pitch up to 5 mrad per keyframe (ImuAttitude... below)
  p.odometry.information.min_std_yaw = 0.001;
  p.odometry.information.max_std_yaw = 0.02;
  p.odometry.information.max_std_xyz = 0.25;
  // The test street's buildings stand 2-6 m apart, never touching: with priors misplaced by
  // 0.8 m, shared-wall detection would tie neighbours that are not (corner error 0.05 -> 0.32 m
  // in NonRigidModeCorrectsEachBuilding). Shared walls are measured on the Karlsruhe drives.
  p.buildings.use_shared_walls = false;
  return p;
}

double ate(const GraphBackend& backend) {
  return evaluateTrajectory(backend.trajectory(), drive().trueTrajectory()).ate.mean;
}

/// ATE of the odometry alone (keyframes 0.1 s apart, as the drive feeds them).
template <typename Poses>
double odometryAte(const Poses& odom) {
  Trajectory t;
  for (size_t k = 0; k < odom.size(); ++k) t.push_back({0.1 * k, odom[k]});
  return evaluateTrajectory(t, drive().trueTrajectory()).ate.mean;
}

/// Extent of an outline along the street (the drive's x axis).
double outlineMinX(const Building& b) {
  double m = 1e9;
  for (const auto& v : b.outline_enu) m = std::min(m, v.x());
  return m;
}
double outlineMaxX(const Building& b) {
  double m = -1e9;
  for (const auto& v : b.outline_enu) m = std::max(m, v.x());
  return m;
}

}  // namespace

TEST(OdometryInformation, YawHasItsOwnDeviationsScaledByFitness) {
  InformationParams p;
  p.min_std_xyz = 0.01;
  p.max_std_xyz = 0.2;
  p.min_std_rot = 0.002;
  p.max_std_rot = 0.02;
  p.min_std_yaw = 0.0001;
  p.max_std_yaw = 0.001;
  p.max_fitness = 0.5;
  const Matrix6d best = odometryInformation(0.0, p);
  EXPECT_DOUBLE_EQ(best(0, 0), 1.0 / (0.01 * 0.01));
  EXPECT_DOUBLE_EQ(best(3, 3), 1.0 / (0.002 * 0.002));  // roll
  EXPECT_DOUBLE_EQ(best(4, 4), 1.0 / (0.002 * 0.002));  // pitch
  EXPECT_DOUBLE_EQ(best(5, 5), 1.0 / (0.0001 * 0.0001));
  const Matrix6d half = odometryInformation(0.25, p);  // halfway: std 0.105 m, 0.011, 0.00055 rad
  EXPECT_NEAR(half(1, 1), 1.0 / (0.105 * 0.105), 1e-9);
  EXPECT_NEAR(half(4, 4), 1.0 / (0.011 * 0.011), 1e-6);
  EXPECT_NEAR(half(5, 5), 1.0 / (0.00055 * 0.00055), 1e-3);
  EXPECT_EQ(odometryInformation(5.0, p), odometryInformation(0.5, p));    // clamped at the maximum
  EXPECT_EQ(odometryInformation(-1.0, p), odometryInformation(0.25, p));  // unknown: the middle
  EXPECT_TRUE((best - Matrix6d(best.diagonal().asDiagonal())).isZero());
}

// A measurement that pins a wall 20 m from the building's vertex: turning the building about
// that wall costs only the heading information; turning it about its vertex moves the wall.
TEST(LeverInformation, RotationAboutTheMatchedWallCostsOnlyHeading) {
  Eigen::Matrix3d at_wall = Eigen::Matrix3d::Zero();
  at_wall(1, 1) = 25.0;   // the wall's normal (y)
  at_wall(0, 0) = 1e-6;   // along the wall: unobserved
  at_wall(2, 2) = 250.0;  // heading
  const Eigen::Vector2d lever(20.0, 0.0);
  const Eigen::Matrix3d at_vertex = leverInformation(at_wall, lever);
  const double dtheta = 0.01;
  auto cost = [&](const Eigen::Vector3d& d) { return d.dot(at_vertex * d); };
  // About the wall: the vertex moves by -dtheta x lever = (0, -0.2).
  EXPECT_NEAR(cost({0.0, -dtheta * lever.x(), dtheta}), 250.0 * dtheta * dtheta, 1e-9);
  // About the vertex: the wall moves 0.2 m across itself.
  EXPECT_NEAR(cost({0.0, 0.0, dtheta}), 250.0 * dtheta * dtheta + 25.0 * 0.04, 1e-9);
  // Sliding along the wall stays (almost) free, and a zero lever changes nothing.
  EXPECT_LT(cost({1.0, 0.0, 0.0}), 1e-5);
  EXPECT_TRUE(leverInformation(at_wall, Eigen::Vector2d::Zero()).isApprox(at_wall));
}

// The Hessian of a match, given for a left perturbation d (X = Exp(d) Z in the target frame),
// must cost the same as PoseGraph's edge error of X against Z: e = (R_z^T (t_x - t_z),
// vec(q_z^-1 q_x)).
TEST(RegistrationInformation, CostsWhatTheHessianCostsInTheEdgeError) {
  Matrix6d a;
  a << 3, 1, 0, 0, 2, 0, 1, 5, 1, 0, 0, 1, 0, 1, 4, 1, 0, 0, 0, 0, 1, 6, 1, 0, 2, 0, 0, 1, 7, 2, 0,
      1, 0, 0, 2, 9;
  const Matrix6d h = 1e4 * a.transpose() * a;  // symmetric, positive definite, coupled
  Eigen::Isometry3d z = Eigen::Isometry3d::Identity();
  z.translation() << 1.9, -0.3, 0.05;
  z.linear() = (Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  const Matrix6d info = registrationInformation(h, z);
  EXPECT_TRUE(info.isApprox(info.transpose()));
  const Eigen::Quaterniond qz(z.linear());
  for (int k = 0; k < 12; ++k) {
    Eigen::Matrix<double, 6, 1> d = 1e-4 * Eigen::Matrix<double, 6, 1>::Random();
    Eigen::Isometry3d left = Eigen::Isometry3d::Identity();  // GICP's update: p' = R(phi) p + rho
    left.linear() =
        Eigen::AngleAxisd(d.tail<3>().norm(), d.tail<3>().normalized()).toRotationMatrix();
    left.translation() = d.head<3>();
    const Eigen::Isometry3d x = left * z;
    Eigen::Quaterniond qe = qz.conjugate() * Eigen::Quaterniond(x.linear());
    if (qe.w() < 0.0) qe.coeffs() *= -1.0;
    Eigen::Matrix<double, 6, 1> e;
    e << z.linear().transpose() * (x.translation() - z.translation()), qe.vec();
    const double expected = d.dot(h * d), got = e.dot(info * e);
    EXPECT_NEAR(got, expected, 1e-3 * expected) << "perturbation " << k;
  }
}

TEST(RegistrationInformation, TranslationMarginalAndAddedDeviation) {
  // Translation x coupled with yaw (a match that pins a point 10 m to the side): knowing the yaw
  // would pin x (A = 1e4), not knowing it leaves the Schur complement.
  Matrix6d info = Matrix6d::Identity() * 1e4;
  info(0, 5) = info(5, 0) = 9e3;
  const Eigen::Matrix3d marginal = translationMarginal(info);
  EXPECT_NEAR(marginal(0, 0), 1e4 - 9e3 * 9e3 / 1e4, 1e-6);
  EXPECT_NEAR(marginal(1, 1), 1e4, 1e-6);
  Matrix6d blind = info;
  blind.bottomRightCorner<3, 3>().setZero();  // no rotation information: no translation claim
  EXPECT_TRUE(translationMarginal(blind).isZero());
  // (info^-1 + e e^T)^-1: x (1 cm) loosened by an offset of 10 cm along x, z (10 cm) kept; also
  // with a direction info does not constrain (y).
  const Eigen::Matrix3d diag = Eigen::Vector3d(1e4, 0.0, 1e2).asDiagonal();
  const Eigen::Matrix3d inflated = withDeviationAlong(diag, Eigen::Vector3d(0.1, 0.0, 0.0));
  EXPECT_NEAR(inflated(0, 0), 1.0 / (1e-4 + 1e-2), 1e-9);
  EXPECT_NEAR(inflated(1, 1), 0.0, 1e-12);
  EXPECT_NEAR(inflated(2, 2), 1e2, 1e-9);
  EXPECT_TRUE(withDeviationAlong(diag, Eigen::Vector3d::Zero()).isApprox(diag));
  // A diagonal offset: the information along it is 1 / (its variance + |e|^2).
  const Eigen::Matrix3d iso = Eigen::Matrix3d::Identity() * 1e4;
  const Eigen::Vector3d e(0.06, 0.08, 0.0);  // 10 cm
  const Eigen::Vector3d u = e.normalized(), side(-u.y(), u.x(), 0.0);
  const Eigen::Matrix3d loose = withDeviationAlong(iso, e);
  EXPECT_NEAR(u.dot(loose * u), 1.0 / (1e-4 + 1e-2), 1e-6);
  EXPECT_NEAR(side.dot(loose * side), 1e4, 1e-6);
}

TEST(OdometryInformation, TranslationAcrossTheMotionIsTighterByTheLateralRatio) {
  InformationParams p;
  p.min_std_xyz = 0.02;
  p.lateral_std_ratio = 0.25;
  const Eigen::Vector3d forward(1.0, 1.0, 0.0);  // diagonal: not just a scaled diagonal matrix
  const Matrix6d info = odometryInformation(0.0, p, 2.0 * forward);
  const Eigen::Matrix3d t = info.topLeftCorner<3, 3>();
  const Eigen::Vector3d along = forward.normalized(), side(-along.y(), along.x(), 0.0);
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(along.dot(t * along), 1.0 / (0.02 * 0.02), 1e-6);
  EXPECT_NEAR(side.dot(t * side), 1.0 / (0.005 * 0.005), 1e-6);
  EXPECT_NEAR(up.dot(t * up), 1.0 / (0.005 * 0.005), 1e-6);
  EXPECT_NEAR(along.dot(t * side), 0.0, 1e-6);
  EXPECT_TRUE(t.isApprox(t.transpose()));
  // Rotation blocks are unchanged; tiny motions have no direction and stay isotropic.
  EXPECT_TRUE(
      (info.bottomRightCorner<3, 3>() == odometryInformation(0.0, p).bottomRightCorner<3, 3>()));
  const Matrix6d still = odometryInformation(0.0, p, Eigen::Vector3d(0.01, 0.0, 0.0));
  EXPECT_DOUBLE_EQ(still(0, 0), 1.0 / (0.02 * 0.02));
  EXPECT_DOUBLE_EQ(still(1, 1), 1.0 / (0.02 * 0.02));
  p.lateral_std_ratio = 1.0;
  EXPECT_EQ(odometryInformation(0.0, p, 2.0 * forward), odometryInformation(0.0, p));
}

TEST(GraphBackend, SimulatedKeyframesHaveWallSegments) {
  for (const auto& segs : drive().segments) EXPECT_GE(segs.size(), 4u);
}

TEST(GraphBackend, PriorModeCorrectsDriftingOdometryWithAnExactMap) {
  const auto odom = drive().odometry(0.004, 1.01);
  GraphBackendParams params = baseParams(OsmMode::kPrior);
  params.association.global_prior_std_xy = 0.05;  // the map is exact here: trust it
  params.association.global_prior_std_yaw = 0.005;
  GraphBackend backend(params);
  drive().feed(backend, odom, drive().truth);
  const BackendUpdateReport r = backend.update();
  EXPECT_EQ(r.keyframes_added, drive().true_poses.size());
  EXPECT_GT(r.global_priors, drive().true_poses.size() * 2 / 3);
  EXPECT_EQ(r.building_edges, 0u);  // buildings are fixed in prior mode

  const double odom_ate = odometryAte(odom);
  EXPECT_GT(odom_ate, 0.8);
  EXPECT_LT(ate(backend), 0.10) << "odometry-only ATE " << odom_ate;
  std::cout << "prior mode: odometry ATE " << odom_ate << " m, SLAM ATE " << ate(backend) << " m\n";
  // Buildings untouched.
  const BuildingErrors b = evaluateBuildings(backend.correctedBuildings(), drive().truth);
  EXPECT_LT(b.max_corner_error, 1e-9);
}

TEST(GraphBackend, WithoutOsmBuildingsAreIgnoredAndNotSaved) {
  const auto odom = drive().odometry(0.002, 1.005);
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.use_osm = false;
  GraphBackend backend(params);
  drive().feed(backend, odom, drive().truth);
  const BackendUpdateReport r = backend.update();
  EXPECT_EQ(r.keyframes_added, drive().true_poses.size());
  EXPECT_EQ(r.buildings_added, 0u);
  EXPECT_EQ(r.building_edges, 0u);
  // save_map writes correctedBuildings(): the baseline must not present the prior as a result.
  EXPECT_TRUE(backend.correctedBuildings().empty());
  EXPECT_NEAR(ate(backend), odometryAte(odom), 1e-6);  // odometry only, nothing to correct it
}

TEST(GraphBackend, NonRigidModeCorrectsEachBuilding) {
  const auto odom = drive().odometry(0.0005, 1.001);
  const auto prior = drive().perturbedPrior(0.8, 0.03, Pose2(), 5);
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.association.global_prior_std_xy = 2.0;  // a noisy map: its global priors weigh little here
  params.association.global_prior_std_yaw = 0.05;
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

TEST(GraphBackend, TheReportSaysWhereTheUpdatesTimeWent) {
  // Each stage is timed inside the update: all ran, and together they fit in its total.
  GraphBackend backend(baseParams(OsmMode::kNonRigid));
  drive().feed(backend, drive().odometry(0.0005, 1.001), drive().perturbedPrior(0.8, 0.03, {}, 5));
  const BackendUpdateReport r = backend.update();
  const BackendUpdateReport::StageMs& t = r.stage_ms;
  for (double ms : {t.osm, t.phase1, t.phase2, t.joint, t.overlaps}) EXPECT_GT(ms, 0.0);
  EXPECT_LE(t.osm + t.phase1 + t.phase2 + t.joint + t.overlaps, r.total_ms);
  BackendUpdateReport::StageMs sum;
  sum += t;
  sum += t;
  EXPECT_DOUBLE_EQ(sum.joint, 2.0 * t.joint);
  EXPECT_DOUBLE_EQ(sum.overlaps, 2.0 * t.overlaps);
}

// The default: no global priors, buildings and robots optimised together. Every building is
// misplaced on its own (0.8 m, 1.7 deg) and odometry drifts; the buildings' priors, each counted
// once however often it is seen, correct both the drift and the buildings.
TEST(GraphBackend, JointOptimizationCorrectsDriftAndBuildings) {
  const auto odom = drive().odometry(0.002, 1.005);
  const auto prior = drive().perturbedPrior(0.8, 0.03, Pose2(), 9);
  const double odom_ate = odometryAte(odom);

  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  GraphBackendParams two_phase = params;
  two_phase.schedule.joint_optimization = false;
  GraphBackend joint(params), phases(two_phase);
  drive().feed(joint, odom, prior);
  drive().feed(phases, odom, prior);
  const BackendUpdateReport r = joint.update();
  phases.update();
  EXPECT_EQ(r.global_priors, 0u);
  EXPECT_GT(r.building_edges, 50u);
  EXPECT_EQ(r.overlaps_remaining, 0u);
  const BuildingErrors before = evaluateBuildings(prior, drive().truth);
  const BuildingErrors after = evaluateBuildings(joint.correctedBuildings(), drive().truth);
  const BuildingErrors after_phases = evaluateBuildings(phases.correctedBuildings(), drive().truth);
  std::cout << "joint: odometry ATE " << odom_ate << " m, two phases " << ate(phases)
            << " m, joint " << ate(joint) << " m; buildings " << before.mean_corner_error << " -> "
            << after_phases.mean_corner_error << " (two phases) / " << after.mean_corner_error
            << " m (joint)\n";
  EXPECT_GT(odom_ate, 0.5);
  EXPECT_LT(ate(joint), 0.5 * odom_ate);
  EXPECT_LT(after.mean_corner_error, 0.5 * before.mean_corner_error);
  EXPECT_LT(after.mean_corner_error, after_phases.mean_corner_error);
}

TEST(GraphBackend, RigidModeRecoversACommonMapShift) {
  const auto odom = drive().odometry(0.0, 1.0);
  const Pose2 shift(0.9, -0.6, 0.01);
  const auto prior = drive().perturbedPrior(0.0, 0.0, shift, 5);
  GraphBackendParams params = baseParams(OsmMode::kRigid);
  params.association.global_prior_std_xy = 20.0;  // trust the (exact) odometry, move the map
  params.association.global_prior_std_yaw = 1.0;
  params.gnss.anchor_std_xy = 0.0;  // ... and the first keyframe's (exact) fix
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
  params.buildings.resolve_overlaps = false;
  params.schedule.joint_optimization = false;  // the thesis' two phases
  params.association.use_global_priors = true;
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
  const double push = outlineMinX(prior[4]) - outlineMaxX(prior[3]) + 2.0;
  prior[3] = toBuilding(prior[3].id, transformPolygon(prior[3].outline_enu, Pose2(push, 0, 0)));
  ASSERT_EQ(findOverlappingBuildings(prior).size(), 1u);

  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.association.local_edge_std_xy =
      100.0;  // isolate the overlap step: the scans barely move buildings
  params.association.local_edge_std_theta = 10.0;
  GraphBackend resolved(params);
  params.buildings.resolve_overlaps = false;
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

TEST(GraphBackend, AnOverlapTheEdgesLeaveIsClearedByTheShortestTranslationOfOneBuilding) {
  // No separation edge at all (0 iterations): the projection alone must clear building 3's 2 m
  // overlap with building 4, moving one of the two by about 2 m and nothing else.
  const auto odom = drive().odometry(0.0, 1.0);
  std::vector<Building> prior = drive().truth;
  const double push = outlineMinX(prior[4]) - outlineMaxX(prior[3]) + 2.0;
  prior[3] = toBuilding(prior[3].id, transformPolygon(prior[3].outline_enu, Pose2(push, 0, 0)));
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.association.local_edge_std_xy = 100.0;  // the scans barely move buildings
  params.association.local_edge_std_theta = 10.0;
  params.buildings.overlap_max_iterations = 0;
  auto run = [&](double reach) {
    params.buildings.overlap_projection_max_translation = reach;
    GraphBackend backend(params);
    drive().feed(backend, odom, prior);
    const BackendUpdateReport r = backend.update();
    return std::make_pair(r, backend.correctedBuildings());
  };
  const auto [left, unprojected] = run(0.0);
  EXPECT_EQ(left.overlaps_remaining, 1u);
  const auto [r, projected] = run(2.5);
  EXPECT_EQ(r.overlaps_projected, 1u);
  EXPECT_EQ(r.overlaps_remaining, 0u);
  EXPECT_TRUE(findOverlappingBuildings(projected).empty());
  EXPECT_EQ(run(1.5).first.overlaps_remaining, 1u) << "2 m is beyond a 1.5 m reach";
  ASSERT_EQ(projected.size(), unprojected.size());
  std::vector<double> moved;
  for (size_t i = 0; i < projected.size(); ++i) {
    moved.push_back(
        (projected[i].reference_pose.translation() - unprojected[i].reference_pose.translation())
            .norm());
    if (projected[i].id != prior[3].id && projected[i].id != prior[4].id)
      EXPECT_LT(moved.back(), 1e-9) << "building " << projected[i].id << " is not involved";
  }
  std::sort(moved.begin(), moved.end());
  EXPECT_NEAR(moved.back(), 2.0, 0.04) << "the shortest way out, plus the clearance";
  EXPECT_LT(moved[moved.size() - 2], 1e-9) << "only one of the two moves";
}

namespace {

/// Priors with buildings 3 and 5 pushed along the street into building 4 from both sides.
std::vector<Building> squeezedPrior() {
  std::vector<Building> prior = drive().truth;
  const double push3 = outlineMinX(prior[4]) - outlineMaxX(prior[3]) + 0.5;
  const double push5 = outlineMaxX(prior[4]) - outlineMinX(prior[5]) - 0.5;
  prior[3] = toBuilding(prior[3].id, transformPolygon(prior[3].outline_enu, Pose2(push3, 0, 0)));
  prior[5] = toBuilding(prior[5].id, transformPolygon(prior[5].outline_enu, Pose2(push5, 0, 0)));
  return prior;
}

}  // namespace

TEST(GraphBackend, OverlapResolutionSeparatesABuildingSqueezedFromBothSides) {
  const std::vector<Building> prior = squeezedPrior();
  ASSERT_EQ(findOverlappingBuildings(prior).size(), 2u);
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  ASSERT_GT(params.buildings.overlap_clearance, 0.0);
  GraphBackend backend(params);
  drive().feed(backend, drive().odometry(0.0, 1.0), prior);
  const BackendUpdateReport r = backend.update();
  EXPECT_EQ(r.overlaps_remaining, 0u);
  EXPECT_TRUE(findOverlappingBuildings(backend.correctedBuildings(), 0.0).empty())
      << "separated buildings keep a clearance, not a compromise overlap";
}

TEST(GraphBackend, ABuildingNobodySawFollowsTheRowHouseItSharesAWallWithOnlyWhenAllowed) {
  // Eight touching houses north of the street, a backyard building behind the third one (hidden
  // from the street), a detached house south. Priors: the backyard building 1.5 m off across
  // the wall it shares, two middle houses 1.5 m and 1 m off along the street.
  std::vector<SimBuilding> scene;
  double x = -38.0;
  for (double width : {10.0, 8.0, 12.0, 9.0, 11.0, 10.0, 9.0, 12.0}) {
    scene.push_back(rectangleBuilding(x, 7.0, width, 12.0, 0.0));
    x += width;
  }
  scene.push_back(rectangleBuilding(-19.0, 19.0, 10.0, 6.0, 0.0));  // backyard, behind house 2
  scene.push_back(rectangleBuilding(-20.0, -20.0, 15.0, 12.0, 0.0));
  const StreetDrive row(scene, 30, 2.5, false);
  std::vector<Building> prior = row.truth;
  auto move = [&](size_t i, const Pose2& by) {
    prior[i] = toBuilding(prior[i].id, transformPolygon(prior[i].outline_enu, by));
  };
  move(3, Pose2(1.5, 0, 0));
  move(5, Pose2(-1.0, 0, 0));
  move(8, Pose2(0.4, 1.5, 0));

  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.initial_yaw = row.true_poses[0].theta;
  params.buildings.shared_walls.max_distance = 2.5;  // config/sim.yaml: priors misplaced one by one
  // By default a building nobody saw follows its neighbour; held at its prior: checked at the end.
  params.osm_prior.unobserved_buildings_fixed = false;
  auto error = [&](const GraphBackend& backend, size_t i) {
    for (const auto& b : backend.correctedBuildings())
      if (b.id == row.truth[i].id)
        return Eigen::Vector2d(b.reference_pose.translation() -
                               row.truth[i].reference_pose.translation());
    return Eigen::Vector2d(HUGE_VAL, HUGE_VAL);
  };
  params.buildings.use_shared_walls = true;
  GraphBackend shared(params);
  params.buildings.use_shared_walls = false;
  GraphBackend without(params);
  row.feed(shared, row.odometry(0.0, 1.0), prior);
  row.feed(without, row.odometry(0.0, 1.0), prior);
  const BackendUpdateReport r = shared.update();
  without.update();
  EXPECT_GE(r.shared_walls, 8u) << "the row's seven shared walls and the backyard's";
  EXPECT_EQ(r.overlaps_remaining, 0u);
  std::cout << "shared walls: backyard building " << error(without, 8).y() << " -> "
            << error(shared, 8).y() << " m across its shared wall; middle houses "
            << error(shared, 3).norm() << " / " << error(shared, 5).norm() << " m\n";
  EXPECT_GT(std::abs(error(without, 8).y()), 1.4) << "nothing else informs it";
  EXPECT_LT(std::abs(error(shared, 8).y()), 0.1);
  EXPECT_NEAR(error(shared, 8).x(), 0.4, 0.1) << "nothing informs it along the wall";
  EXPECT_LT(error(shared, 3).norm(), 0.15);
  EXPECT_LT(error(shared, 5).norm(), 0.15);
  EXPECT_LT(error(shared, 9).norm(), 0.1) << "the detached house shares no wall";

  // unobserved_buildings_fixed: the backyard building stays exactly at its prior, the row is
  // corrected alike.
  params.buildings.use_shared_walls = true;
  params.osm_prior.unobserved_buildings_fixed = true;
  GraphBackend held(params);
  row.feed(held, row.odometry(0.0, 1.0), prior);
  const BackendUpdateReport h = held.update();
  EXPECT_EQ(h.overlaps_remaining, 0u);
  EXPECT_NEAR(error(held, 8).x(), 0.4, 1e-6) << "unobserved: exactly its prior";
  EXPECT_NEAR(error(held, 8).y(), 1.5, 1e-6);
  EXPECT_LT(error(held, 3).norm(), 0.15);
  EXPECT_LT(error(held, 5).norm(), 0.15);
}

TEST(GraphBackend, FirstKeyframeIsFixedAtItsGnssPositionNotAtTheOrigin) {
  // The first six scans never became keyframes (dropped at start-up): the vehicle is 12 m past
  // the first fix, which is the map origin.
  constexpr size_t kFirst = 6;
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.use_osm = false;
  params.initial_yaw = drive().true_poses[kFirst].theta;
  GraphBackend at_origin(params), at_gnss(params);
  const auto odom = drive().odometry(0.0, 1.0);
  drive().feed(at_origin, odom, {}, std::nullopt, kFirst);
  drive().feed(at_gnss, odom, {}, std::nullopt, kFirst, true);
  at_origin.update();
  at_gnss.update();
  const double offset = drive().true_poses[kFirst].translation().norm();
  ASSERT_GT(offset, 5.0);
  EXPECT_NEAR(ate(at_origin), offset, 0.01);
  EXPECT_LT(ate(at_gnss), 0.01);
  // A heading found later (odometry's frame is 0.5 rad off) is applied about the first keyframe,
  // which stays where GNSS put it.
  params.initial_yaw_known = false;
  std::vector<Eigen::Isometry3d> turned;
  for (const auto& pose : odom) turned.push_back(isometryFromPlanar(Pose2(3.0, -1.0, 0.5)) * pose);
  GraphBackend late_heading(params);
  drive().feed(late_heading, turned, {}, std::nullopt, kFirst, true);
  late_heading.update();
  EXPECT_GT(ate(late_heading), 1.0);
  late_heading.setInitialHeading(drive().true_poses[kFirst].theta);
  late_heading.update();
  EXPECT_LT(ate(late_heading), 0.01);
}

TEST(GraphBackend, AHeadingGivenBeforeTheFirstKeyframeAnchorsItLikeTheParameter) {
  // The nodelet gives the IMU's heading by setInitialHeading() just before the first keyframe;
  // offline runners set it as a parameter. Both must anchor the first keyframe the same way
  // (softly, at anchor_std_xy), not fixed in one and soft in the other.
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.use_osm = false;
  params.initial_yaw_known = true;
  params.initial_yaw = drive().true_poses[0].theta;
  GraphBackend by_param(params);
  params.initial_yaw_known = false;
  GraphBackend by_call(params);
  by_call.setInitialHeading(drive().true_poses[0].theta);
  const auto odom = drive().odometry(0.0, 1.0);
  drive().feed(by_param, odom, {}, std::nullopt, 0, true);
  drive().feed(by_call, odom, {}, std::nullopt, 0, true);
  by_param.update();
  by_call.update();
  const int first = static_cast<int>(by_param.keyframes().front().id);
  EXPECT_FALSE(by_param.graphSnapshot().isFixed(first));
  EXPECT_FALSE(by_call.graphSnapshot().isFixed(first));
  const Trajectory a = by_param.trajectory(), b = by_call.trajectory();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i)
    EXPECT_LT((a[i].pose.translation() - b[i].pose.translation()).norm(), 1e-9) << i;
}

TEST(GraphBackend, ImuAttitudeKeepsTheTrajectoryLevel) {
  // Odometry that pitches 0.3 deg per keyframe: the trajectory dives; an IMU knows it is level.
  auto odom = drive().odometry(0.002, 1.005);
  for (size_t k = 1; k < odom.size(); ++k) {
    Eigen::Isometry3d pitch = Eigen::Isometry3d::Identity();
    pitch.linear() = Eigen::AngleAxisd(0.005 * k, Eigen::Vector3d::UnitY()).toRotationMatrix();
    odom[k] = odom[k] * pitch;  // attitude error only: positions come from re-integration below
  }
  std::vector<Eigen::Isometry3d> dived = {odom[0]};
  for (size_t k = 1; k < odom.size(); ++k) {
    Eigen::Isometry3d step =
        drive().odometry(0.002, 1.005)[k - 1].inverse() * drive().odometry(0.002, 1.005)[k];
    step.linear() = odom[k - 1].linear().transpose() * odom[k].linear();
    dived.push_back(dived.back() * step);
  }
  auto max_abs_z = [](const Trajectory& t) {
    double z = 0.0;
    for (const auto& sp : t) z = std::max(z, std::abs(sp.pose.translation().z()));
    return z;
  };
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  GraphBackend without_imu(params), with_imu(params);
  drive().feed(without_imu, dived, drive().truth);
  drive().feed(with_imu, dived, drive().truth, Eigen::Vector2d::Zero());  // the drive is level
  without_imu.update();
  with_imu.update();
  const double z_without = max_abs_z(without_imu.trajectory());
  const double z_with = max_abs_z(with_imu.trajectory());
  EXPECT_GT(z_without, 2.0);
  EXPECT_LT(z_with, 0.3);
  EXPECT_LT(ate(with_imu), 0.5);
  std::cout << "pitching odometry: max |z| " << z_without << " m without IMU, " << z_with
            << " m with IMU attitude priors; ATE " << ate(without_imu) << " -> " << ate(with_imu)
            << " m\n";
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
  EXPECT_EQ(r.building_edges, 0u);  // no buildings yet
  backend.addBuildings(drive().truth, Eigen::Vector2d::Zero(), 1000.0);
  r = backend.update();
  EXPECT_GT(r.building_edges, 10u);
}

TEST(GraphBackend, KeyframesThatNeverArriveAreCountedAndWarnedOnceAndOdometryBridgesThem) {
  // The 35-minute soak lost keyframes in an overflowed subscription queue without a word.
  std::vector<std::string> warnings;
  auto logger = std::make_shared<Logger>([&](LogLevel level, const std::string& msg) {
    if (level == LogLevel::kWarn) warnings.push_back(msg);
  });
  GraphBackend backend(baseParams(OsmMode::kPrior), logger);
  const auto odom = drive().odometry(0.0, 1.0);
  auto add = [&](size_t k) {
    KeyframeInput kf;
    kf.id = k;
    kf.stamp = 0.1 * k;
    kf.odom_pose = odom[k];
    backend.addKeyframe(kf);
  };
  for (size_t k : {0, 1, 2, 6, 7}) add(k);  // 3..5 lost
  BackendUpdateReport r = backend.update();
  EXPECT_EQ(r.keyframes_missing, 3u);
  for (size_t k : {8, 9, 12}) add(k);  // 10, 11 lost
  r = backend.update();
  EXPECT_EQ(r.keyframes_missing, 2u);
  EXPECT_EQ(backend.missingKeyframes(), 5u);
  EXPECT_EQ(backend.numKeyframes(), 8u);
  size_t gap_warnings = 0;
  for (const auto& w : warnings)
    if (w.find("never reached the back-end") != std::string::npos) {
      ++gap_warnings;
      EXPECT_NE(w.find("ids 3..5"), std::string::npos) << w;
    }
  EXPECT_EQ(gap_warnings, 1u);  // once, with the first gap
  // Odometry across the gap: the graph keeps the odometry's relative pose 2 -> 6.
  const auto kfs = backend.keyframes();
  const auto at = [&](uint64_t id) {
    return std::find_if(kfs.begin(), kfs.end(), [&](const auto& k) { return k.id == id; })
        ->map_pose;
  };
  const Eigen::Isometry3d rel = at(2).inverse() * at(6);
  const Eigen::Isometry3d expected = odom[2].inverse() * odom[6];
  EXPECT_LT((rel.translation() - expected.translation()).norm(), 1e-3);
}

TEST(SequenceGaps, CountsSkippedIdsNotDuplicatesOrLateOnes) {
  SequenceGaps gaps;
  EXPECT_EQ(gaps.observe(7), 0u);  // the first id may be anything (a nodelet started late)
  EXPECT_EQ(gaps.observe(8), 0u);
  EXPECT_EQ(gaps.observe(12), 3u);
  EXPECT_EQ(gaps.lastGap(), "ids 9..11");
  EXPECT_EQ(gaps.observe(12), 0u);  // duplicate
  EXPECT_EQ(gaps.observe(10), 0u);  // late: already counted, the last id stays 12
  EXPECT_EQ(gaps.observe(13), 0u);
  EXPECT_EQ(gaps.observe(15), 1u);
  EXPECT_EQ(gaps.missing(), 4u);
}

TEST(OptimizationSchedule, ASlowUpdateStretchesTheWaitToTheDutyCycle) {
  EXPECT_DOUBLE_EQ(optimizationWait(3.0, 0.2, 0.5), 3.0);    // small graph: the period
  EXPECT_DOUBLE_EQ(optimizationWait(3.0, 5.0, 0.5), 5.0);    // idle as long as it worked
  EXPECT_DOUBLE_EQ(optimizationWait(3.0, 5.0, 0.25), 15.0);  // a quarter of a core
  EXPECT_DOUBLE_EQ(optimizationWait(3.0, 50.0, 1.0), 3.0);   // no limit
  EXPECT_DOUBLE_EQ(optimizationWait(3.0, 50.0, 0.0), 3.0);   // no limit either
}

TEST(OptimizationSchedule, KeyframeDrivenUpdatesComeEveryNKeyframesOrWhenTheyStop) {
  EXPECT_FALSE(keyframeUpdateDue(14, 0, 15, 0.1, 3.0));  // 14 of 15, keyframes still coming
  EXPECT_TRUE(keyframeUpdateDue(15, 0, 15, 0.1, 3.0));
  EXPECT_TRUE(keyframeUpdateDue(32, 15, 15, 0.0, 3.0));    // a slow update: 17 waited
  EXPECT_FALSE(keyframeUpdateDue(20, 15, 15, 2.9, 3.0));   // not idle long enough yet
  EXPECT_TRUE(keyframeUpdateDue(20, 15, 15, 3.0, 3.0));    // the bag ended: the rest
  EXPECT_FALSE(keyframeUpdateDue(15, 15, 15, 60.0, 3.0));  // nothing new: no update
  EXPECT_TRUE(keyframeUpdateDue(1, 0, 0, 0.0, 3.0));       // every < 1 counts as every keyframe
}

TEST(GraphBackend, AKeyframeStampedBeforeThePreviousIsKeptAndItsFloorNotTied) {
  // A looped bag: the tracker restarted at keyframe 5, stamped back at the drive's start, on the
  // last pose and flagged re-anchored; its floor is the start's, unrelated to keyframe 4's.
  std::vector<std::string> warnings;
  auto logger = std::make_shared<Logger>([&](LogLevel level, const std::string& msg) {
    if (level == LogLevel::kWarn) warnings.push_back(msg);
  });
  GraphBackend backend(noOsmKnownHeading(), logger);
  const Eigen::Vector4d level(0.0, 0.0, 1.0, 0.93);
  for (uint64_t i = 0; i < 5; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.floor = level;
    backend.addKeyframe(kf);
  }
  EXPECT_EQ(backend.update(true).floor_edges, 4u);
  const std::vector<KeyframeState> before = backend.keyframes();

  KeyframeInput restart = straightKeyframe(4);
  restart.id = 5;
  restart.stamp = straightKeyframe(0).stamp;
  restart.reanchored = true;
  restart.floor = Eigen::Vector4d(0.0, 0.0, 1.0, 2.5);  // 1.6 m lower ground
  backend.addKeyframe(restart);
  const BackendUpdateReport r = backend.update(true);
  EXPECT_EQ(r.keyframes_added, 1u);
  EXPECT_EQ(r.floor_edges, 0u);
  EXPECT_EQ(r.floor_gaps, 1u);
  ASSERT_EQ(backend.numKeyframes(), 6u);
  const std::vector<KeyframeState> after = backend.keyframes();
  for (size_t i = 0; i < before.size(); ++i)
    EXPECT_LT((after[i].map_pose.translation() - before[i].map_pose.translation()).norm(), 1e-6)
        << "keyframe " << i << " moved";
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("the time jumped back"), std::string::npos) << warnings[0];
}

TEST(GraphBackend, TheFirstLoopAfterAJumpBackPlacesTheNewPassWithoutMovingTheOldOne) {
  // A looped bag: keyframes 5..7 are the start again (x = 0, 2, 4 m), but the tracker restarted
  // on its last pose (x = 8 m) and went on from there. Loop 5 -> 0 says where they are; the robust
  // loop kernel alone lost against the restart's provisional link (fault_injection.test: 20.9 m).
  std::vector<std::string> infos;
  auto logger = std::make_shared<Logger>([&](LogLevel level, const std::string& msg) {
    if (level == LogLevel::kInfo) infos.push_back(msg);
  });
  GraphBackend backend(noOsmKnownHeading(), logger);
  for (uint64_t i = 0; i < 5; ++i) backend.addKeyframe(straightKeyframe(i));
  backend.update(true);
  const std::vector<KeyframeState> before = backend.keyframes();
  for (uint64_t i = 5; i < 8; ++i) {
    KeyframeInput kf = straightKeyframe(i - 1);  // odometry goes on from keyframe 4's pose
    kf.id = i;
    kf.stamp = straightKeyframe(i - 5).stamp;
    kf.reanchored = i == 5;
    backend.addKeyframe(kf);
  }
  backend.update(true);
  EXPECT_NEAR(backend.keyframes()[5].map_pose.translation().x(), 8.0, 1e-3);  // hangs there
  LoopClosureInput loop;
  loop.from_id = 5;
  loop.to_id = 0;
  loop.information = Matrix6d::Identity() * 1e4;
  backend.addLoopClosure(loop);
  backend.update(true);
  const std::vector<KeyframeState> after = backend.keyframes();
  ASSERT_EQ(after.size(), 8u);
  for (uint64_t i = 5; i < 8; ++i)
    EXPECT_LT((after[i].map_pose.translation() - Eigen::Vector3d(2.0 * (i - 5), 0, 0)).norm(), 0.05)
        << "keyframe " << i;
  for (size_t i = 0; i < before.size(); ++i)
    EXPECT_LT((after[i].map_pose.translation() - before[i].map_pose.translation()).norm(), 0.01)
        << "keyframe " << i << " of the first pass moved";
  const bool said = std::any_of(infos.begin(), infos.end(), [](const std::string& m) {
    return m.find("placed by loop 5 -> 0") != std::string::npos;
  });
  EXPECT_TRUE(said);
  // A later loop into the old pass is an ordinary loop: nothing is placed again.
  loop.from_id = 7;
  loop.to_id = 2;
  backend.addLoopClosure(loop);
  backend.update(true);
  EXPECT_LT((backend.keyframes()[7].map_pose.translation() - Eigen::Vector3d(4.0, 0, 0)).norm(),
            0.05);
}

namespace {

struct ShiftedMapRun {
  double ate = 0.0;
  double buildings_before = 0.0, buildings_after = 0.0;
  size_t reassociated = 0;
  Pose2 datum;
};

/// Exact odometry, honest deviations, the first keyframe fixed at its exact fix.
GraphBackendParams shiftedMapParams() {
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.gnss.anchor_std_xy = 0.0;
  params.odometry.information.max_std_xyz = 0.05;  // exact odometry, honest deviations
  return params;
}

/// The drive through a prior shifted as a whole by 2.5 m (plus 0.2 m per building): everything
/// OSM does to the trajectory is damage. gnss: exact fixes on every keyframe.
ShiftedMapRun shiftedMapRun(const GraphBackendParams& params, bool gnss) {
  const auto odom = drive().odometry(0.0, 1.0);
  const auto prior = drive().perturbedPrior(0.2, 0.0, Pose2(1.5, -2.0, 0.0), 17);
  GraphBackend backend(params);
  drive().feed(backend, odom, prior, std::nullopt, 0, gnss);
  ShiftedMapRun run;
  // Updates every 6 keyframes, as the nodelet's timer would: the datum is learnt on the way.
  for (int i = 0; i < 8; ++i) run.reassociated += backend.update(true).osm_reassociated;
  run.ate = ate(backend);
  run.buildings_before = evaluateBuildings(prior, drive().truth).mean_corner_error;
  run.buildings_after =
      evaluateBuildings(backend.correctedBuildings(), drive().truth).mean_corner_error;
  run.datum = backend.osmDatum().value_or(Pose2());
  return run;
}

/// ... with no GNSS after the first fix: the map's priors take their ..._without_gnss deviations.
ShiftedMapRun shiftedMapRun(double datum_std, const std::string& datum_kernel = "none",
                            double building_prior_std = 0.0) {
  GraphBackendParams params = shiftedMapParams();
  params.osm_prior.osm_datum_std_xy_without_gnss = datum_std;
  params.osm_prior.osm_datum_kernel_without_gnss = datum_kernel;
  if (building_prior_std > 0.0)
    params.osm_prior.building_prior_std_xy_without_gnss = building_prior_std;
  return shiftedMapRun(params, false);
}

}  // namespace

TEST(GraphBackend, AMapShiftedAsAWholeMovesTheDatumNotTheTrajectory) {
  const ShiftedMapRun absolute = shiftedMapRun(0.0), datum = shiftedMapRun(3.0);
  std::printf(
      "[datum] ATE absolute priors %.3f m, datum %.3f m (datum %.2f %.2f); buildings "
      "%.3f -> %.3f / %.3f m; %zu keyframes re-associated\n",
      absolute.ate, datum.ate, datum.datum.x, datum.datum.y, datum.buildings_before,
      absolute.buildings_after, datum.buildings_after, datum.reassociated);
  EXPECT_LT(datum.ate, 0.5 * absolute.ate);
  EXPECT_LT(datum.ate, 0.1);
  EXPECT_NEAR(datum.datum.x, -1.5, 0.3);
  EXPECT_NEAR(datum.datum.y, 2.0, 0.3);
  EXPECT_LT(datum.buildings_after, 0.3);
}

TEST(GraphBackend, ARobustDatumLetsGoOfAMapShiftedFarBeyondItsDeviation) {
  // Building priors of a building's misplacement (1.5 m) make the map's common offset evidence;
  // a datum held at 1 m then drags the trajectory 2.5 m towards the shifted map, unless its
  // Cauchy kernel lets go.
  const ShiftedMapRun tight = shiftedMapRun(1.0, "none", 1.5);
  const ShiftedMapRun robust = shiftedMapRun(1.0, "cauchy", 1.5);
  std::printf("[datum kernel] ATE none %.3f m (datum %.2f %.2f), cauchy %.3f m (datum %.2f %.2f)\n",
              tight.ate, tight.datum.x, tight.datum.y, robust.ate, robust.datum.x, robust.datum.y);
  EXPECT_LT(robust.ate, 0.5 * tight.ate);
  EXPECT_GT(robust.datum.translation().norm(), 1.5);
}

TEST(GraphBackend, TheDatumsReassociationDistanceFollowsWhetherFixesHoldTheRun) {
  // Each run reads its own distance: with fixes on every keyframe osm_datum_reassociate_distance,
  // with the first fix only ..._without_gnss (the datum travels metres there).
  auto reassociated = [](bool gnss, double distance, double distance_without_gnss) {
    GraphBackendParams params = shiftedMapParams();
    params.osm_prior.osm_datum_reassociate_distance = distance;
    params.osm_prior.osm_datum_reassociate_distance_without_gnss = distance_without_gnss;
    return shiftedMapRun(params, gnss).reassociated;
  };
  const size_t with_fixes = reassociated(true, 0.3, 0.0);
  const size_t first_fix_only = reassociated(false, 0.0, 0.3);
  std::printf("[reassociation] with fixes %zu keyframes, first fix only %zu\n", with_fixes,
              first_fix_only);
  EXPECT_GT(with_fixes, 0u);
  EXPECT_GT(first_fix_only, 0u);
  EXPECT_EQ(reassociated(true, 0.0, 0.3), 0u);
  EXPECT_EQ(reassociated(false, 0.3, 0.0), 0u);
  EXPECT_EQ(reassociated(true, 100.0, 0.3), 0u);
}

namespace {

/// Keyframe i of N around a circle of radius 20 m from the origin, the odometry turning 0.01 rad
/// per keyframe too far (it drifts off the circle), the truth in `truth` if given.
KeyframeInput circleKeyframe(int i, int n, Eigen::Isometry3d* truth = nullptr) {
  auto poseAt = [&](int k, double extra_yaw) {
    Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
    start.linear() = Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    // The true step, applied k times, each with the odometry's yaw error.
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.translation() = Eigen::Vector3d(2.0 * 20.0 * std::sin(M_PI / n), 0.0, 0.0);
    step.linear() =
        Eigen::AngleAxisd(2.0 * M_PI / n + extra_yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Eigen::Isometry3d pose = start;  // at the origin, heading north: keyframe 0 in the map
    const Eigen::Isometry3d half_turn(
        Eigen::AngleAxisd(M_PI / n, Eigen::Vector3d::UnitZ()).toRotationMatrix());
    for (int j = 0; j < k; ++j) pose = pose * half_turn * step * half_turn.inverse();
    return pose;
  };
  KeyframeInput kf;
  kf.id = static_cast<uint64_t>(i);
  kf.stamp = 1.0 + i;
  kf.odom_pose = poseAt(i, 0.01);
  kf.accum_distance = 2.0 * 20.0 * std::sin(M_PI / n) * i;
  kf.odom_fitness = 0.05;
  if (truth) *truth = poseAt(i, 0.0);
  return kf;
}

}  // namespace

TEST(GraphBackend, AWindowedUpdateHoldsTheOldKeyframesAndADisagreeingLoopCallsAFullBatch) {
  constexpr int kN = 40, kWindow = 10;
  GraphBackendParams params = noOsmKnownHeading();
  params.initial_yaw = M_PI / 2.0;
  params.loops.loop_kernel =
      "none";                 // the loop below is right; Cauchy would doubt a 7 m correction
  GraphBackend full(params);  // the reference: a full batch every update
  params.schedule.optimization_window = kWindow;
  GraphBackend windowed(params);
  std::vector<Eigen::Isometry3d> truth(kN);
  for (int i = 0; i < kN; ++i) {
    const std::vector<KeyframeState> before = windowed.keyframes();
    const KeyframeInput kf = circleKeyframe(i, kN, &truth[i]);
    windowed.addKeyframe(kf);
    full.addKeyframe(kf);
    full.update();
    const BackendUpdateReport r = windowed.update();
    if (i + 1 <= kWindow) {
      EXPECT_FALSE(r.window_start) << "keyframe " << i << ": the whole graph fits the window";
      continue;
    }
    ASSERT_TRUE(r.window_start);
    EXPECT_EQ(*r.window_start, static_cast<uint64_t>(i + 1 - kWindow));
    const std::vector<KeyframeState> after = windowed.keyframes();
    for (uint64_t k = 0; k < *r.window_start; ++k)
      EXPECT_TRUE(after[k].map_pose.isApprox(before[k].map_pose, 0.0)) << "held keyframe " << k;
  }
  // Odometry alone: the two agree.
  const auto farSideError = [&](const GraphBackend& b) {
    return (b.keyframes()[kN / 2].map_pose.translation() - truth[kN / 2].translation()).norm();
  };
  const auto endError = [&](const GraphBackend& b) {
    return (b.keyframes()[kN - 1].map_pose.translation() - truth[kN - 1].translation()).norm();
  };
  const double drift = farSideError(windowed);
  EXPECT_NEAR(drift, farSideError(full), 1e-3);
  const double end_drift = endError(windowed);
  EXPECT_GT(end_drift, 5.0);
  // The odometry turned 0.4 rad too far around the circle: the loop back to the start disagrees
  // with the held part, which only a full batch can bend.
  LoopClosureInput loop;
  loop.from_id = kN - 1;
  loop.to_id = 0;
  loop.relative_pose = truth[0].inverse() * truth[kN - 1];
  loop.information = Matrix6d::Identity() * 1e3;
  windowed.addLoopClosure(loop);
  full.addLoopClosure(loop);
  full.update();
  BackendUpdateReport r = windowed.update();
  EXPECT_TRUE(r.full_batch_for_loop);
  EXPECT_FALSE(r.window_start);
  EXPECT_NEAR(farSideError(windowed), farSideError(full), 0.01);
  EXPECT_LT(endError(windowed), 0.1 * end_drift) << "the loop did not close";
  // A second loop that now agrees stays in the window.
  const std::vector<KeyframeState> closed = windowed.keyframes();
  loop.from_id = kN - 2;
  loop.to_id = 1;
  loop.relative_pose = closed[1].map_pose.inverse() * closed[kN - 2].map_pose;
  windowed.addLoopClosure(loop);
  windowed.addKeyframe(circleKeyframe(kN, kN));
  r = windowed.update();
  EXPECT_FALSE(r.full_batch_for_loop);
  EXPECT_TRUE(r.window_start);
  // A forced update (save_map) is a full batch.
  r = windowed.update(true);
  EXPECT_FALSE(r.window_start);
}

// A free scale of an old path window would keep every old odometry edge in a windowed update's
// problem (measured: the 1.5 km Karlsruhe replay's back-end took 48 % longer with the scale on).
TEST(GraphBackend, AWindowedUpdateHoldsTheScalesOfOldPathWindows) {
  constexpr int kN = 40, kWindow = 10;
  GraphBackendParams params = noOsmKnownHeading();
  params.initial_yaw = M_PI / 2.0;
  params.odometry.odometry_scale_window = 20.0;  // 3.14 m steps: one scale per 6-7 keyframes
  params.schedule.optimization_window = kWindow;
  GraphBackend windowed(params);
  BackendUpdateReport r;
  for (int i = 0; i < kN; ++i) {
    windowed.addKeyframe(circleKeyframe(i, kN));
    r = windowed.update();
  }
  ASSERT_TRUE(r.window_start);
  ASSERT_EQ(windowed.odometryScales().size(), 7u);
  // Keyframes 30-39 are free (94-123 m): their 10 odometry edges, the walks into the scales of
  // the path windows 4-6 they lie in, and the 4 older steps of window 4 (80-94 m) that observe
  // its scale too; nothing older (without holding the old scales: all 39 steps and 6 walks).
  EXPECT_EQ(r.phase1.num_edges, kWindow + 3 + 4);
  // A forced update (save_map) frees everything again.
  r = windowed.update(true);
  EXPECT_GE(r.phase1.num_edges, kN - 1 + 6);
}

TEST(PoseGraph, LeavingOutEdgesBetweenFixedVerticesGivesTheSameSolution) {
  auto build = [] {
    PoseGraph g;
    for (int i = 0; i < 6; ++i) {
      Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
      p.translation().x() = 1.1 * i;
      g.addVertexSE3(i, p, i < 3);
    }
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.translation().x() = 1.0;
    for (int i = 0; i + 1 < 6; ++i) g.addEdgeSE3(i, i + 1, step, Matrix6d::Identity());
    return g;
  };
  PoseGraph all = build(), skipped = build();
  OptimizerOptions options;
  const OptimizationResult ra = all.optimize(0, options);
  options.skip_constant_edges = true;
  const OptimizationResult rs = skipped.optimize(0, options);
  EXPECT_EQ(ra.num_edges, 5);
  EXPECT_EQ(rs.num_edges, 3);  // 0-1 and 1-2 join fixed vertices
  for (int i = 0; i < 6; ++i)
    EXPECT_LT((all.vertexSE3(i)->translation() - skipped.vertexSE3(i)->translation()).norm(), 1e-9);
  EXPECT_NEAR(skipped.vertexSE3(5)->translation().x(), 5.2, 1e-6);
}

namespace {

/// The street drive with a fix on every keyframe that reports 1.5 m; keyframes 14-25 drive
/// between tall rows and their fixes are reflections 10 m across the street (NLOS), still
/// reporting 1.5 m. Returns the mean error of those keyframes' positions.
double nlosRunError(const std::string& kernel, double gate, bool use_osm) {
  GraphBackendParams params = baseParams(OsmMode::kNonRigid);
  params.use_osm = use_osm;
  params.gnss.gnss_prior_std = 1.5;
  params.gnss.gnss_prior_kernel = kernel;
  params.gnss.gnss_innovation_gate = gate;
  GraphBackend backend(params);
  const auto odom = drive().odometry(0.002, 1.005);
  backend.addBuildings(drive().perturbedPrior(0.3, 0.01, Pose2(0.0, 0.0, 0.0), 5),
                       Eigen::Vector2d::Zero(), 1000.0);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.8);
  for (size_t k = 0; k < odom.size(); ++k) {
    KeyframeInput kf = drive().keyframe(k, odom);
    const bool nlos = k >= 14 && k <= 25;
    kf.gnss_position = drive().true_poses[k].translation() +
                       Eigen::Vector2d(noise(rng), noise(rng) + (nlos ? 10.0 : 0.0));
    kf.gnss_std = 1.5;
    backend.addKeyframe(kf);
    backend.addLineSegments(k, drive().segments[k]);
    if (k % 6 == 5) backend.update();  // the gate predicts from the last update
  }
  backend.update(true);
  const Trajectory t = backend.trajectory();
  double sum = 0.0;
  for (size_t k = 14; k <= 25; ++k)
    sum += (t[k].pose.translation().head<2>() - drive().true_poses[k].translation()).norm();
  return sum / 12.0;
}

}  // namespace

// Reflected fixes claim metres of accuracy they do not have: the innovation gate keeps them out,
// and the redescending kernel lets odometry, the good fixes and the walls hold the trajectory
// against those that pass it.
TEST(GnssPrior, ARunOfReflectedFixesDoesNotPullATrajectoryThatOdometryAndWallsHold) {
  const GnssParams defaults;
  const double huber = nlosRunError("huber", 0.0, true), cauchy = nlosRunError("cauchy", 0.0, true);
  const double gated =
      nlosRunError(defaults.gnss_prior_kernel, defaults.gnss_innovation_gate, true);
  const double gated_without_walls =
      nlosRunError(defaults.gnss_prior_kernel, defaults.gnss_innovation_gate, false);
  std::printf(
      "[gnss_prior] mean error under 10 m NLOS fixes: huber %.3f m, cauchy %.3f m, defaults "
      "(cauchy + gate) %.3f m, without walls %.3f m\n",
      huber, cauchy, gated, gated_without_walls);
  EXPECT_GT(huber, 2.0 * cauchy);  // Huber's pull does not fall with the distance
  EXPECT_LT(cauchy, 0.5);
  EXPECT_LT(gated, 0.33);    // measured 0.302 m
  EXPECT_LT(gated, cauchy);  // the gate keeps the worst lies out
  EXPECT_LT(gated_without_walls, 0.5);
}
