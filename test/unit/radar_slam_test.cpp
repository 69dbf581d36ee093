// Radar scan-to-map registration (radar_registration.h) and the radar SLAM back-end
// (radar_slam.h): the motion/Doppler compensation of a sweep's points against a hand computation,
// point-to-line alignment on a synthetic street (accuracy, degeneracy, too few points, the
// convergence basin that makes the odometry's yaw hypotheses necessary), the local map's keyframe
// window, the radar Scan Context's yaw convention, the back-end on a simulated drive that returns
// to its start, and the parameter checks.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <random>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/radar/radar_motion.h"
#include "osm_graph_slam/radar/radar_registration.h"
#include "osm_graph_slam/radar/radar_slam.h"
#include "osm_graph_slam/sim/radar_sim.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::radar;

namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Isometry2d pose2(double x, double y, double yaw_deg) {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() = Eigen::Rotation2Dd(yaw_deg * kDeg).toRotationMatrix();
  T.translation() << x, y;
  return T;
}

struct Segment {
  Eigen::Vector2d a, b;
};

/// Points every `spacing` metres along each segment (starting `offset` metres in), with
/// gaussian noise of `noise` metres on both coordinates.
std::vector<Eigen::Vector2d> sampleWalls(const std::vector<Segment>& walls, double spacing,
                                         double offset, double noise, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise > 0 ? noise : 1.0);
  std::vector<Eigen::Vector2d> out;
  for (const Segment& w : walls) {
    const double length = (w.b - w.a).norm();
    const Eigen::Vector2d u = (w.b - w.a) / length;
    for (double s = offset; s <= length; s += spacing) {
      Eigen::Vector2d p = w.a + s * u;
      if (noise > 0) p += Eigen::Vector2d(n(rng), n(rng));
      out.push_back(p);
    }
  }
  return out;
}

/// A street corner: two long walls meeting at a right angle and a diagonal facade.
std::vector<Segment> street() {
  return {{{-30.0, 8.0}, {30.0, 8.0}},      // along x, left of the road
          {{18.0, 8.0}, {18.0, -25.0}},     // along y, ahead
          {{-25.0, -8.0}, {-5.0, -19.5}}};  // 30 deg diagonal, behind right
}

std::vector<Eigen::Vector2d> transformed(const Eigen::Isometry2d& T,
                                         const std::vector<Eigen::Vector2d>& points) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(points.size());
  for (const Eigen::Vector2d& p : points) out.push_back(T * p);
  return out;
}

Eigen::Isometry2d planar(const Eigen::Isometry3d& P) {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() =
      Eigen::Rotation2Dd(std::atan2(P.linear()(1, 0), P.linear()(0, 0))).toRotationMatrix();
  T.translation() = P.translation().head<2>();
  return T;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// compensatedPoints
// ---------------------------------------------------------------------------------------------

TEST(RadarCompensation, StaticSensorGivesRangeTimesClockwiseBeam) {
  std::vector<RadarFeature> fs(3);
  fs[0].range = 10.0;
  fs[0].azimuth = 0.0;
  fs[1].range = 20.0;
  fs[1].azimuth = M_PI / 2;  // clockwise: to the right, -y
  fs[2].range = 12.5;
  fs[2].azimuth = 30 * kDeg;
  for (RadarFeature& f : fs) f.time = 0.17;  // not t_ref: with zero velocity it must not matter
  const auto cw = compensatedPoints(fs, Eigen::Vector3d::Zero(), 0.05, 0.0, true, true);
  ASSERT_EQ(cw.size(), 3u);
  EXPECT_NEAR((cw[0] - Eigen::Vector2d(10.0, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((cw[1] - Eigen::Vector2d(0.0, -20.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((cw[2] - 12.5 * Eigen::Vector2d(std::cos(M_PI / 6), -0.5)).norm(), 0.0, 1e-12);
  // Counter-clockwise azimuths mirror y.
  const auto ccw = compensatedPoints(fs, Eigen::Vector3d::Zero(), 0.05, 0.0, false, true);
  EXPECT_NEAR((ccw[1] - Eigen::Vector2d(0.0, 20.0)).norm(), 0.0, 1e-12);
  // beta without velocity: no shift either.
  const auto beta = compensatedPoints(fs, Eigen::Vector3d::Zero(), 0.05, 0.049, true, true);
  EXPECT_NEAR((beta[2] - cw[2]).norm(), 0.0, 1e-12);
}

TEST(RadarCompensation, MovingSensorAgainstAHandComputation) {
  RadarFeature f;
  f.range = 20.0;
  f.azimuth = M_PI / 2;  // beam (0, -1)
  f.time = 1.30;
  const double t_ref = 1.20, beta = 0.049;
  const Eigen::Vector3d w(10.0, 2.0, 0.4);  // vx, vy, omega
  const auto out = compensatedPoints({f}, w, t_ref, beta, true, true);
  ASSERT_EQ(out.size(), 1u);
  // Doppler (eq. 7.9): r + beta v.u = 20 + 0.049 * (2 * -1) = 19.902, along (0, -1).
  const double r = 20.0 - 0.049 * 2.0;
  const Eigen::Vector2d p(0.0, -r);
  // The sensor at t = 1.30 seen from the sensor at t_ref: rotation theta = omega dt = 0.04,
  // translation V(theta) v dt with V = [sin/th, -(1-cos)/th; (1-cos)/th, sin/th].
  const double dt = 0.10, th = 0.4 * dt;
  const double a = std::sin(th) / th, b = (1.0 - std::cos(th)) / th;
  const Eigen::Vector2d trans((a * 10.0 - b * 2.0) * dt, (b * 10.0 + a * 2.0) * dt);
  const Eigen::Vector2d expected(std::cos(th) * p.x() - std::sin(th) * p.y() + trans.x(),
                                 std::sin(th) * p.x() + std::cos(th) * p.y() + trans.y());
  // (1.7916, -19.6661) instead of (0, -19.902): a sign error in time or rotation cannot hide.
  EXPECT_NEAR(expected.x(), 1.79160, 1e-4);
  EXPECT_NEAR(expected.y(), -19.66614, 1e-4);
  EXPECT_NEAR((out[0] - expected).norm(), 0.0, 1e-9) << out[0].transpose();
  // The same through se2Exp.
  EXPECT_NEAR((out[0] - se2Exp(w, f.time - t_ref) * p).norm(), 0.0, 1e-12);
  // Without motion compensation the time is left out: only the Doppler correction remains.
  const auto still = compensatedPoints({f}, w, t_ref, beta, true, false);
  EXPECT_NEAR((still[0] - p).norm(), 0.0, 1e-12) << still[0].transpose();
  // Without Doppler (beta 0) the range is the measured one.
  const auto no_doppler = compensatedPoints({f}, w, t_ref, 0.0, true, false);
  EXPECT_NEAR((no_doppler[0] - Eigen::Vector2d(0.0, -20.0)).norm(), 0.0, 1e-12);
  // A feature before t_ref moves the other way.
  f.time = 1.10;
  const auto before = compensatedPoints({f}, w, t_ref, beta, true, true);
  EXPECT_NEAR((before[0] - se2Exp(w, -0.10) * p).norm(), 0.0, 1e-12);
  EXPECT_GT((before[0] - out[0]).norm(), 1.5);
}

// ---------------------------------------------------------------------------------------------
// PlanarPointMap::align
// ---------------------------------------------------------------------------------------------

TEST(RadarRegistration, AlignRecoversAnOffsetPoseOnAStreet) {
  const RadarRegistrationParams params;
  PlanarPointMap map;
  map.build(sampleWalls(street(), 0.3, 0.0, 0.02, 1), params);
  ASSERT_GT(map.size(), 300u);
  const Eigen::Isometry2d truth = pose2(1.2, -0.8, 4.0);
  // The same walls sampled elsewhere along them, other noise, in the sensor frame at truth.
  const auto scan = transformed(truth.inverse(), sampleWalls(street(), 0.3, 0.15, 0.02, 2));
  const RadarAlignment a = map.align(scan, Eigen::Isometry2d::Identity(), params);
  ASSERT_TRUE(a.ok);
  const double dt = (a.pose.translation() - truth.translation()).norm();
  const double dyaw = std::abs(yawOf(a.pose) - yawOf(truth)) / kDeg;
  // Measured 0.004 m, 0.001 deg, 387 of 387 points matched, rms 0.032 m.
  EXPECT_LT(dt, 0.02);
  EXPECT_LT(dyaw, 0.05);
  EXPECT_GT(a.correspondences, int(0.95 * scan.size()));
  EXPECT_LT(a.rms, 0.05);
  // Information: positive definite (three well-posed directions).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(a.information);
  EXPECT_GT(es.eigenvalues()(0), 0.0);
}

// Along one straight wall nothing constrains the translation parallel to it: align must say so.
TEST(RadarRegistration, OneExactStraightWallIsRefused) {
  const RadarRegistrationParams params;
  const std::vector<Segment> wall = {{{-30.0, 8.0}, {30.0, 8.0}}};
  const Eigen::Isometry2d truth = pose2(1.2, -0.8, 4.0);
  PlanarPointMap map;
  map.build(sampleWalls(wall, 0.3, 0.0, 0.0, 1), params);
  const auto scan = transformed(truth.inverse(), sampleWalls(wall, 0.3, 0.15, 0.0, 2));
  const RadarAlignment a = map.align(scan, Eigen::Isometry2d::Identity(), params);
  EXPECT_FALSE(a.ok);
  // Refused for the degeneracy, not for too few correspondences (measured 130).
  EXPECT_GE(a.correspondences, params.min_correspondences);
  // A second, non-parallel wall makes the same scan well-posed.
  const std::vector<Segment> corner = {wall[0], {{18.0, 8.0}, {18.0, -25.0}}};
  PlanarPointMap map2;
  map2.build(sampleWalls(corner, 0.3, 0.0, 0.0, 1), params);
  const RadarAlignment b =
      map2.align(transformed(truth.inverse(), sampleWalls(corner, 0.3, 0.15, 0.0, 2)),
                 Eigen::Isometry2d::Identity(), params);
  ASSERT_TRUE(b.ok);
  EXPECT_LT((b.pose.translation() - truth.translation()).norm(), 0.02);
}

// A noisy single wall: fitted normals scatter by a few hundredths of a radian, which lifted the
// smallest information eigenvalue above the old absolute floor (1e-6) and let the pose slide
// 1.6 m along the wall as a "valid" registration. The test is now relative, on the translation
// information with the yaw marginalised (min_translation_ratio).
TEST(RadarRegistration, OneNoisyStraightWallIsRefused) {
  const RadarRegistrationParams params;
  const std::vector<Segment> wall = {{{-30.0, 8.0}, {30.0, 8.0}}};
  const Eigen::Isometry2d truth = pose2(1.2, -0.8, 4.0);
  PlanarPointMap map;
  map.build(sampleWalls(wall, 0.3, 0.0, 0.02, 1), params);
  const auto scan = transformed(truth.inverse(), sampleWalls(wall, 0.3, 0.15, 0.02, 2));
  const RadarAlignment a = map.align(scan, Eigen::Isometry2d::Identity(), params);
  EXPECT_FALSE(a.ok) << "accepted with an along-wall error of "
                     << (a.pose.translation() - truth.translation()).x() << " m";
}

TEST(RadarRegistration, TooFewPointsAreNotTrusted) {
  const RadarRegistrationParams params;
  PlanarPointMap map;
  map.build(sampleWalls(street(), 0.3, 0.0, 0.02, 1), params);
  const Eigen::Isometry2d truth = pose2(1.2, -0.8, 4.0);
  const auto all = transformed(truth.inverse(), sampleWalls(street(), 0.3, 0.15, 0.02, 2));
  // Every 5th point (all walls represented), truncated to exactly the minimum and one less.
  std::vector<Eigen::Vector2d> sparse;
  for (size_t i = 0; i < all.size(); i += 5) sparse.push_back(all[i]);
  ASSERT_GT(sparse.size(), size_t(params.min_correspondences));
  sparse.resize(size_t(params.min_correspondences));
  const RadarAlignment enough = map.align(sparse, truth, params);
  EXPECT_TRUE(enough.ok);
  EXPECT_EQ(enough.correspondences, params.min_correspondences);
  sparse.pop_back();
  const RadarAlignment few = map.align(sparse, truth, params);
  EXPECT_FALSE(few.ok);
  EXPECT_EQ(few.correspondences, params.min_correspondences - 1);
  // Points farther than max_correspondence from the map do not count: the full scan placed
  // 280 m away finds no partner.
  const RadarAlignment far = map.align(all, pose2(200.0, 200.0, 0.0), params);
  EXPECT_FALSE(far.ok);
  EXPECT_EQ(far.correspondences, 0);
  // An empty map or an empty scan: not ok.
  EXPECT_FALSE(PlanarPointMap().align(all, truth, params).ok);
  EXPECT_FALSE(map.align({}, truth, params).ok);
}

// Why RadarOdometry tries yaw hypotheses after a poor match: in a corridor (two long parallel
// walls, poles along the kerbs) a prediction 15 deg off in yaw settles on a wrong pose that align
// still calls ok, with few correspondences; from 3 deg it finds the truth. Measured: the basin
// ends between 11 and 12 deg here (on the street corner above it reaches 25 deg). If the basin
// changes (correspondence radius, iterations, robust kernel), this test says so.
TEST(RadarRegistration, ConvergenceBasinInYaw) {
  const RadarRegistrationParams params;
  const std::vector<Segment> corridor = {{{-60, 7}, {60, 7}}, {{-60, -7}, {60, -7}}};
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 0.02);
  std::vector<Eigen::Vector2d> poles;
  for (double x = -55; x <= 55; x += 8) {
    poles.push_back({x, 5.5});
    poles.push_back({x + 4, -5.5});
  }
  std::vector<Eigen::Vector2d> map_points = sampleWalls(corridor, 0.3, 0.0, 0.02, 1);
  std::vector<Eigen::Vector2d> world_scan = sampleWalls(corridor, 0.3, 0.15, 0.02, 2);
  for (const Eigen::Vector2d& q : poles) {
    map_points.push_back(q + Eigen::Vector2d(n(rng), n(rng)));
    world_scan.push_back(q + Eigen::Vector2d(n(rng), n(rng)));
  }
  PlanarPointMap map;
  map.build(map_points, params);
  const Eigen::Isometry2d truth = pose2(1.2, -0.8, 4.0);
  const auto scan = transformed(truth.inverse(), world_scan);
  const double n_scan = double(scan.size());
  auto errorOf = [&](const RadarAlignment& a, double* dyaw_deg) {
    *dyaw_deg = std::abs(yawOf(truth.inverse() * a.pose)) / kDeg;
    return (a.pose.translation() - truth.translation()).norm();
  };
  for (double sign : {-1.0, 1.0}) {
    double dyaw;
    const RadarAlignment near = map.align(scan, truth * pose2(0, 0, sign * 3.0), params);
    ASSERT_TRUE(near.ok);
    EXPECT_LT(errorOf(near, &dyaw), 0.02) << sign;
    EXPECT_LT(dyaw, 0.05) << sign;
    EXPECT_GT(near.correspondences, 0.95 * n_scan);

    const RadarAlignment off = map.align(scan, truth * pose2(0, 0, sign * 15.0), params);
    errorOf(off, &dyaw);
    EXPECT_GT(dyaw, 10.0) << sign;  // measured 14.8 deg: stuck near the guess
    // ok is no convergence test; the overlap is what RadarOdometry reads (search_below_overlap).
    EXPECT_LT(off.correspondences, params.search_below_overlap * n_scan)
        << off.correspondences << " of " << n_scan;  // measured 190 of 828

    // The hypotheses (RadarOdometry::refine: every yaw_search_step_deg up to yaw_search_deg
    // around the guess, the most correspondences kept) recover the truth from 15 deg.
    RadarAlignment best = off;
    const Eigen::Isometry2d guess = truth * pose2(0, 0, sign * 15.0);
    for (double d = params.yaw_search_step_deg; d <= params.yaw_search_deg + 1e-9;
         d += params.yaw_search_step_deg)
      for (double s : {-1.0, 1.0}) {
        const RadarAlignment b = map.align(scan, guess * pose2(0, 0, s * d), params);
        if (b.ok && b.correspondences > best.correspondences) best = b;
      }
    EXPECT_LT(errorOf(best, &dyaw), 0.02) << sign;
    EXPECT_LT(dyaw, 0.05) << sign;
  }
}

// The local map holds the last submap_keyframes keyframes, each moved by its pose.
TEST(RadarLocalMap, KeyframesInTheOdometryFrameAndTheWindow) {
  RadarRegistrationParams params;
  params.submap_keyframes = 2;
  RadarLocalMap local(params);
  EXPECT_TRUE(local.empty());
  const Eigen::Isometry2d kf0 = pose2(5.0, 2.0, 10.0);
  const auto walls = sampleWalls(street(), 0.3, 0.0, 0.02, 1);
  local.addKeyframe(kf0, transformed(kf0.inverse(), walls));  // points in the keyframe frame
  EXPECT_FALSE(local.empty());
  EXPECT_TRUE(local.lastKeyframePose().isApprox(kf0));
  const Eigen::Isometry2d truth = pose2(1.2, -0.8, 4.0);
  const auto scan = transformed(truth.inverse(), sampleWalls(street(), 0.3, 0.15, 0.02, 2));
  const RadarAlignment a = local.align(scan, Eigen::Isometry2d::Identity());
  ASSERT_TRUE(a.ok);
  EXPECT_LT((a.pose.translation() - truth.translation()).norm(), 0.02);
  EXPECT_LT(std::abs(yawOf(truth.inverse() * a.pose)) / kDeg, 0.05);
  // Two more keyframes far away: the first one leaves the window, nothing is left to match.
  const auto elsewhere = transformed(pose2(500.0, 0.0, 0.0), walls);
  local.addKeyframe(Eigen::Isometry2d::Identity(), elsewhere);
  EXPECT_TRUE(local.align(scan, Eigen::Isometry2d::Identity()).ok);  // kf0 still in
  local.addKeyframe(Eigen::Isometry2d::Identity(), elsewhere);
  const RadarAlignment gone = local.align(scan, Eigen::Isometry2d::Identity());
  EXPECT_FALSE(gone.ok);
  EXPECT_EQ(gone.correspondences, 0);
  local.clear();
  EXPECT_TRUE(local.empty());
}

// ---------------------------------------------------------------------------------------------
// Radar Scan Context
// ---------------------------------------------------------------------------------------------

namespace {

void randomPoints(uint32_t seed, std::vector<Eigen::Vector2d>& points, std::vector<float>& powers) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> r(4.0, 78.0), a(-M_PI, M_PI);
  std::uniform_real_distribution<float> p(60.0f, 255.0f);
  points.clear();
  powers.clear();
  for (int i = 0; i < 600; ++i) {
    const double range = r(rng), angle = a(rng);
    points.emplace_back(range * std::cos(angle), range * std::sin(angle));
    powers.push_back(p(rng));
  }
}

}  // namespace

TEST(RadarScanContext, CellsHoldTheStrongestPowerAndSkipTheNearField) {
  const ScanContextParams params = radarScanContextParams();
  EXPECT_DOUBLE_EQ(params.min_radius, 3.0);
  // Two returns in one cell (10 m ahead), one in the near field, one beyond max_radius.
  const std::vector<Eigen::Vector2d> pts = {{10.0, 0.1}, {10.5, 0.2}, {2.0, 0.0}, {90.0, 0.0}};
  const ScanContext sc = radarScanContext(pts, {100.0f, 200.0f, 255.0f, 255.0f}, params);
  int ring, sector;
  ASSERT_TRUE(scanContextCell(10.0, 0.1, params, &ring, &sector));
  EXPECT_FLOAT_EQ(sc.cells(ring, sector), 200.0f / 255.0f);
  EXPECT_EQ(sc.occupied_cells, 1);
  EXPECT_NEAR(sc.cells.sum(), 200.0f / 255.0f, 1e-6);
}

TEST(RadarScanContext, RotationBySectorsIsRecoveredWithTheDocumentedSign) {
  const ScanContextParams params = radarScanContextParams();
  const double sector = 2 * M_PI / params.num_sectors;  // 6 deg
  std::vector<Eigen::Vector2d> points;
  std::vector<float> powers;
  randomPoints(11, points, powers);
  const ScanContext query = radarScanContext(points, powers, params);
  for (int k : {1, 7, -11, 25}) {
    // The query sensor turned by k sectors against the candidate's: p_cand = Rz(k * 6 deg) p_q.
    const Eigen::Rotation2Dd R(k * sector);
    std::vector<Eigen::Vector2d> rotated;
    for (const Eigen::Vector2d& p : points) rotated.push_back(R * p);
    const ScanContext candidate = radarScanContext(rotated, powers, params);
    const ScanContextMatch m = matchScanContexts(query, candidate, params);
    EXPECT_EQ(m.shift, (k + params.num_sectors) % params.num_sectors) << k;
    EXPECT_NEAR(m.yaw, k * sector, 1e-9) << k;
    EXPECT_LT(m.distance, 0.05) << k;
    // Swapped roles: the opposite yaw.
    EXPECT_NEAR(matchScanContexts(candidate, query, params).yaw, -k * sector, 1e-9) << k;
  }
  // Another place: far.
  std::vector<Eigen::Vector2d> other;
  std::vector<float> other_powers;
  randomPoints(12, other, other_powers);
  const ScanContextMatch m =
      matchScanContexts(query, radarScanContext(other, other_powers, params), params);
  EXPECT_GT(m.distance, 0.3);
}

// ---------------------------------------------------------------------------------------------
// RadarSlam on a simulated drive that returns to its start
// ---------------------------------------------------------------------------------------------

namespace {

struct SlamRun {
  std::vector<Eigen::Isometry2d> truth, odometry, corrected;
  std::vector<size_t> keyframe_sweep;  ///< sweep index of each keyframe
  std::vector<RadarLoop> loops;
  RadarLoopStats stats;
  Eigen::Isometry2d first_world = Eigen::Isometry2d::Identity();  ///< first radar pose, world
};

/// A 3 x 3 block city with 45-60 m blocks; the 200 m route of seed 1 is 303 m long, 168 sweeps,
/// and ends where it started (the route planner returns to its start).
/// feed (may be empty) gets the slam and the time up to which navigation data is due, before
/// each sweep (the sweep's start + 0.5 s) and once more before finish() (infinity).
using NavFeed = std::function<void(RadarSlam&, const sim::RadarSimulator&, double until)>;

SlamRun runSimulatedDrive(const RadarSlamParams& params, const NavFeed& feed = {},
                          std::optional<Eigen::Isometry2d>* map_from_enu = nullptr,
                          RadarNavStats* nav_stats = nullptr) {
  sim::SimulationParams p;
  p.seed = 1;
  p.route.length = 200;
  p.city.blocks_x = 3;
  p.city.blocks_y = 3;
  p.city.block_min = 45;
  p.city.block_max = 60;
  sim::UrbanSimulator world;
  std::string error;
  SlamRun run;
  EXPECT_TRUE(world.build(p, &error)) << error;
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 1);
  RadarSlam slam(params);
  Eigen::Isometry2d first = Eigen::Isometry2d::Identity();
  for (size_t k = 0; k < radar.numScans(); ++k) {
    if (feed) feed(slam, radar, radar.sweepStart(k) + 0.5);
    const RadarOdometryStep step = slam.process(radar.simulate(k));
    const Eigen::Isometry2d g = planar(radar.radarPose(step.time));
    if (k == 0) first = run.first_world = g;
    run.truth.push_back(first.inverse() * g);
    run.odometry.push_back(step.pose);
    if (step.keyframe) run.keyframe_sweep.push_back(k);
  }
  if (feed) feed(slam, radar, std::numeric_limits<double>::infinity());
  slam.finish();
  if (map_from_enu) *map_from_enu = slam.mapFromEnu();
  if (nav_stats) *nav_stats = slam.navStats();
  run.corrected = slam.sweepPoses();
  run.loops = slam.loops();
  run.stats = slam.loopStats();
  EXPECT_EQ(run.keyframe_sweep.size(), slam.numKeyframes());
  return run;
}

/// Each loop's measurement against the truth: translation [m] and yaw [deg] errors.
void expectLoopsAgreeWithTruth(const SlamRun& run, double max_m, double max_deg) {
  for (const RadarLoop& l : run.loops) {
    ASSERT_LT(size_t(l.to), run.keyframe_sweep.size());
    const Eigen::Isometry2d truth = run.truth[run.keyframe_sweep[size_t(l.from)]].inverse() *
                                    run.truth[run.keyframe_sweep[size_t(l.to)]];
    const double dt = (truth.translation() - l.measurement.translation()).norm();
    const double dyaw = std::abs(yawOf(truth.inverse() * l.measurement)) / kDeg;
    EXPECT_LT(dt, max_m) << "loop " << l.from << " - " << l.to;
    EXPECT_LT(dyaw, max_deg) << "loop " << l.from << " - " << l.to;
    EXPECT_LT(l.from, l.to);
  }
}

double endError(const std::vector<Eigen::Isometry2d>& poses, const SlamRun& run) {
  return (poses.back().translation() - run.truth.back().translation()).norm();
}

}  // namespace

TEST(RadarSlamSim, LoopsCloseOnARouteBackToItsStart) {
  const SlamRun run = runSimulatedDrive(RadarSlamParams());
  ASSERT_EQ(run.corrected.size(), run.truth.size());
  ASSERT_EQ(run.odometry.size(), run.truth.size());
  // Measured: 59 keyframes, 4 loops (0-55 .. 0-58, odometry candidates), measurement errors
  // 0.01-0.23 m and 0.1-0.6 deg; end error 0.615 m (odometry) -> 0.111 m (corrected).
  EXPECT_GE(run.loops.size(), 1u);
  EXPECT_EQ(run.stats.accepted, int(run.loops.size()));
  expectLoopsAgreeWithTruth(run, 1.0, 1.5);
  const double odom = endError(run.odometry, run), slam = endError(run.corrected, run);
  EXPECT_GT(odom, 0.3);  // else the drive is too easy to show anything
  EXPECT_LT(slam, 0.5 * odom) << "odometry " << odom << " m, corrected " << slam << " m";
  // The map frame is the first keyframe's odometry frame: the first sweep is not moved.
  EXPECT_TRUE(run.corrected.front().isApprox(run.odometry.front(), 1e-9));
}

// The descriptor path alone (no odometry candidates): the Scan Context's yaw, used as the
// registration guess, has the right sign. On this drive the revisit's descriptor distance is 0.46
// (3 m apart, 90 deg turned), above the default threshold 0.3, hence the wider threshold here.
TEST(RadarSlamSim, ScanContextCandidatesAloneCloseTheLoop) {
  RadarSlamParams params;
  params.loop.search_radius = 0.0;
  params.loop.scan_context_threshold = 0.5;
  const SlamRun run = runSimulatedDrive(params);
  // Measured: 2 candidates, 1 accepted (0-58, 0.05 m / 0.02 deg off), 1 rejected by the gate;
  // end error 0.615 -> 0.184 m.
  ASSERT_GE(run.loops.size(), 1u);
  for (const RadarLoop& l : run.loops) EXPECT_TRUE(l.by_scan_context);
  expectLoopsAgreeWithTruth(run, 1.0, 1.5);
  EXPECT_LT(endError(run.corrected, run), 0.5 * endError(run.odometry, run));
}

// ---------------------------------------------------------------------------------------------
// GNSS fixes and yaw rates in the graph
// ---------------------------------------------------------------------------------------------

namespace {

/// The true ENU frame of the fixes, seen from the simulator's world: rotated 35 deg and shifted,
/// so that nothing works by the frames happening to coincide.
Eigen::Isometry2d enuFromWorld() {
  return pose2(120.0, -40.0, 35.0);
}

/// 10 Hz fixes of the true radar position in that frame with white noise (sigma per axis), one
/// fix `outlier_m` off at t = 20 s when non-zero; 100 Hz yaw rates of the truth plus a bias.
NavFeed simulatedNavigation(double sigma, double outlier_m, double gyro_bias, bool gnss, bool imu) {
  auto state = std::make_shared<std::pair<double, double>>(0.0, 0.0);  // next fix, next rate
  auto rng = std::make_shared<std::mt19937>(7);
  return [=](RadarSlam& slam, const sim::RadarSimulator& radar, double until) {
    const double end = std::min(until, radar.sweepStart(radar.numScans()));
    std::normal_distribution<double> noise(0.0, sigma);
    for (; gnss && state->first <= end; state->first += 0.1) {
      Eigen::Vector2d p = enuFromWorld() * planar(radar.radarPose(state->first)).translation();
      p += Eigen::Vector2d(noise(*rng), noise(*rng));
      if (outlier_m > 0 && std::abs(state->first - 20.0) < 0.05) p.x() += outlier_m;
      slam.addGnssFix(state->first, p, sigma);
    }
    for (; imu && state->second <= end; state->second += 0.01) {
      const double t = state->second, h = 0.005;
      const double rate =
          yawOf(planar(radar.radarPose(t - h)).inverse() * planar(radar.radarPose(t + h))) /
          (2 * h);
      slam.addYawRate(t, rate + gyro_bias);
    }
  };
}

RadarSlamParams navOnly() {
  RadarSlamParams p;
  p.loop.enabled = false;  // what the navigation edges do alone
  return p;
}

/// Worst position error after the best rigid 2D fit of the poses to the truth: the map frame is
/// the first keyframe's, whose heading error the fixes cannot undo, so the first-pose frame would
/// charge the GNSS run with the start's heading error over the whole drive.
double maxAlignedError(const std::vector<Eigen::Isometry2d>& poses, const SlamRun& run) {
  std::vector<Eigen::Vector2d> est, truth;
  for (size_t i = 0; i < poses.size(); ++i) {
    est.push_back(poses[i].translation());
    truth.push_back(run.truth[i].translation());
  }
  const Eigen::Isometry2d T = fitRigid2d(est, truth);
  double worst = 0;
  for (size_t i = 0; i < est.size(); ++i) worst = std::max(worst, (T * est[i] - truth[i]).norm());
  return worst;
}

}  // namespace

// The anchor fitted to the fixes is the true map -> ENU transform, and the fixes hold the
// trajectory: its worst error is below the odometry's and within the fixes' noise.
TEST(RadarSlamNavigation, GnssAnchorsTheMapAndBoundsTheError) {
  std::optional<Eigen::Isometry2d> map_from_enu;
  RadarNavStats stats;
  const SlamRun run = runSimulatedDrive(navOnly(), simulatedNavigation(0.5, 0.0, 0.0, true, false),
                                        &map_from_enu, &stats);
  ASSERT_TRUE(map_from_enu.has_value());
  EXPECT_TRUE(stats.anchored);
  EXPECT_GT(stats.gnss_edges, 20);
  EXPECT_EQ(stats.imu_edges, 0);
  // The anchor places the first keyframe (the map frame) in ENU: A^-1 against E F (F: the first
  // radar pose in the world). Its heading comes from the fixes of the first tens of metres
  // (sigma 0.5 m each), so degrees, not tenths.
  const Eigen::Isometry2d error =
      (enuFromWorld() * run.first_world).inverse() * map_from_enu->inverse();
  EXPECT_LT(error.translation().norm(), 1.0);     // measured 0.50 m
  EXPECT_LT(std::abs(yawOf(error)) / kDeg, 3.0);  // measured 1.80 deg
  const double odom = maxAlignedError(run.odometry, run);
  const double slam = maxAlignedError(run.corrected, run);
  // Measured: 0.760 m -> 0.426 m (odometry: a scale error that grows away from the start).
  EXPECT_LT(slam, 0.7 * odom) << "odometry " << odom << " m, with GNSS " << slam << " m";
  EXPECT_LT(slam, 0.6);
}

/// Mean heading error over the keyframes [deg] (the sweeps after the last keyframe hang from it
/// by odometry alone).
double meanKeyframeYawError(const std::vector<Eigen::Isometry2d>& poses, const SlamRun& run) {
  double sum = 0;
  for (size_t i : run.keyframe_sweep) sum += std::abs(yawOf(run.truth[i].inverse() * poses[i]));
  return sum / double(run.keyframe_sweep.size()) / kDeg;
}

// Yaw-change edges from a biased gyro (0.005 deg/s, a MEMS IMU's in-run bias) take out most of
// the heading the odometry lost.
TEST(RadarSlamNavigation, GyroYawChangesHoldTheHeading) {
  RadarNavStats stats;
  const SlamRun run = runSimulatedDrive(
      navOnly(), simulatedNavigation(0.5, 0.0, 0.005 * kDeg, false, true), nullptr, &stats);
  EXPECT_GT(stats.imu_edges, 40);
  EXPECT_EQ(stats.imu_missing, 0);
  EXPECT_EQ(stats.gnss_edges, 0);
  const double odom = meanKeyframeYawError(run.odometry, run);
  const double slam = meanKeyframeYawError(run.corrected, run);
  std::printf("mean keyframe yaw error: odometry %.3f deg, with gyro %.3f deg\n", odom, slam);
  // Measured: 1.711 -> 0.584 deg. Not to the gyro's 0.1 deg: the odometry edges' yaw sigma
  // (0.1 deg per 5 m) is optimistic for this drive's turns, so they pull back.
  EXPECT_LT(slam, 0.45 * odom);
  EXPECT_LT(slam, 0.8);
}

// A fix 40 m off (multipath) is held by the Huber kernel; fixes with NaN, a huge sigma or an
// older stamp are counted and dropped; yaw rates out of order too.
TEST(RadarSlamNavigation, BadFixesAreCountedAndDoNotDragTheTrajectory) {
  NavFeed good = simulatedNavigation(0.5, 40.0, 0.0, true, true);
  bool injected = false;
  NavFeed feed = [&](RadarSlam& slam, const sim::RadarSimulator& radar, double until) {
    good(slam, radar, until);
    if (injected || until < 10.0) return;
    injected = true;
    slam.addGnssFix(until + 0.01, Eigen::Vector2d(NAN, 0.0), 0.5);
    slam.addGnssFix(until + 0.02, Eigen::Vector2d(0.0, 0.0), 100.0);
    slam.addGnssFix(1.0, Eigen::Vector2d(0.0, 0.0), 0.5);  // older than the last one
    slam.addYawRate(1.0, 0.0);
  };
  RadarNavStats stats;
  const SlamRun run = runSimulatedDrive(navOnly(), feed, nullptr, &stats);
  EXPECT_EQ(stats.gnss_rejected_sigma, 2);
  EXPECT_GE(stats.gnss_out_of_order, 1);
  EXPECT_GE(stats.imu_out_of_order, 1);
  const double slam = maxAlignedError(run.corrected, run);
  std::printf("with a 40 m outlier: %.3f m\n", slam);
  EXPECT_LT(slam, 0.7);
}

// ---------------------------------------------------------------------------------------------
// readSlamParams
// ---------------------------------------------------------------------------------------------

TEST(RadarSlamParams, NegativeLoopSigmaIsRefused) {
  std::string error;
  RadarSlamParams ok_params;
  ASSERT_TRUE(readSlamParams(YamlParamReader::fromString("loop:\n  sigma_translation: 0.5\n"),
                             ok_params, &error))
      << error;
  EXPECT_DOUBLE_EQ(ok_params.loop.sigma_translation, 0.5);
  for (const std::string& yaml : {std::string("loop:\n  sigma_translation: -0.2\n"),
                                  std::string("loop:\n  sigma_translation: 0\n"),
                                  std::string("loop:\n  sigma_yaw_deg: -1\n")}) {
    RadarSlamParams p;
    error.clear();
    EXPECT_FALSE(readSlamParams(YamlParamReader::fromString(yaml), p, &error)) << yaml;
    // The message names the key group ("loop/sigma_*"), not the single key.
    EXPECT_NE(error.find("loop/sigma_"), std::string::npos) << error;
  }
  // An odometry key is still checked first.
  RadarSlamParams p;
  EXPECT_FALSE(
      readSlamParams(YamlParamReader::fromString("features:\n  detector: x\n"), p, &error));
  EXPECT_NE(error.find("features/detector"), std::string::npos) << error;
}
