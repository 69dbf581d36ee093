// Floor detection (ART-SLAM §3.1.6) and the plane-pair edges that tie consecutive keyframes'
// floors in the back-end.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "osm_graph_slam/cloud/floor_detector.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/slam/graph_backend.h"

using namespace osm_graph_slam;

namespace {

constexpr double kDeg = M_PI / 180.0;

/// A filtered-looking scan in base_link: ground on the plane n·p + d = 0 in a ring 2-25 m on a
/// 0.5 m grid (2 cm noise), two building walls and a parked car (planes, but not floor).
PointCloud sceneWithFloor(const Eigen::Vector3d& normal, double d, double noise = 0.02,
                          double max_range = 25.0, unsigned seed = 1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  PointCloud cloud;
  const Eigen::Vector3d n = normal.normalized();
  auto add = [&](double x, double y, double z) {
    PointT p;
    p.x = float(x + noise * n01(rng));
    p.y = float(y + noise * n01(rng));
    p.z = float(z + noise * n01(rng));
    p.intensity = 0.2f;
    cloud.push_back(p);
  };
  for (double x = -max_range; x <= max_range; x += 0.5)
    for (double y = -max_range; y <= max_range; y += 0.5) {
      const double r = std::hypot(x, y);
      if (r < 2.0 || r > max_range) continue;
      add(x, y, -(d + n.x() * x + n.y() * y) / n.z());
    }
  for (double x = -20.0; x <= 20.0; x += 0.5)  // walls at y = +-9 m, 0-8 m above the road
    for (double h = 0.0; h <= 8.0; h += 0.5) {
      add(x, 9.0, h - 0.93);
      add(x, -9.0, h - 0.93);
    }
  for (double x = 4.0; x <= 8.5; x += 0.25)  // a car roof 1.5 m above the road, 2 m wide
    for (double y = 3.0; y <= 5.0; y += 0.25) add(x, y, 0.57);
  return cloud;
}

double angleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
}

}  // namespace

TEST(FloorDetector, RecoversATiltedFloorWithinHalfADegreeAndTwoCentimetres) {
  // The road seen from a vehicle pitched 4 deg and rolled 3 deg (or a road that slopes so).
  const Eigen::Vector3d n = (Eigen::AngleAxisd(4.0 * kDeg, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(3.0 * kDeg, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix()
                                .transpose() *
                            Eigen::Vector3d::UnitZ();
  const double d = 0.93;  // base_link 0.93 m above the road
  const FloorDetection f = FloorDetector().detect(sceneWithFloor(n, d));
  ASSERT_TRUE(f.found) << f.reason;
  EXPECT_EQ(f.method, "ransac");
  const double angle = angleBetween(f.coeffs.head<3>(), n);
  std::printf("[floor] tilted: normal error %.3f deg, offset error %.4f m, %zu inliers, rms %.3f\n",
              angle / kDeg, f.coeffs[3] - d, f.inliers, f.rms);
  EXPECT_LT(angle, 0.5 * kDeg);
  EXPECT_NEAR(f.coeffs[3], d, 0.02);
  EXPECT_GT(f.coeffs[2], 0.0);
  EXPECT_NEAR(floorTilt(f.coeffs), angleBetween(n, Eigen::Vector3d::UnitZ()), 0.5 * kDeg);
}

TEST(FloorDetector, RoughTerrainFallsBackToLeastSquaresNearTheVehicle) {
  // Only the ground close to the vehicle (2-5.5 m) is seen: too little for RANSAC's support.
  FloorDetectorParams p;
  p.min_inliers = 2000;
  const PointCloud cloud = sceneWithFloor(Eigen::Vector3d(0.02, 0.0, 1.0), 0.93, 0.02, 5.5);
  const FloorDetection f = FloorDetector(p).detect(cloud);
  ASSERT_TRUE(f.found) << f.reason;
  EXPECT_EQ(f.method, "least_squares");
  EXPECT_LT(angleBetween(f.coeffs.head<3>(), Eigen::Vector3d(0.02, 0.0, 1.0)), 1.0 * kDeg);
  EXPECT_NEAR(f.coeffs[3], 0.93, 0.03);

  p.rough_radius = 0.0;  // fallback off: no floor, and a reason
  const FloorDetection none = FloorDetector(p).detect(cloud);
  EXPECT_FALSE(none.found);
  EXPECT_NE(none.reason.find("RANSAC support"), std::string::npos) << none.reason;
}

TEST(FloorDetector, NoFloorInACloudOfWallsOrNothing) {
  PointCloud walls;
  for (double x = -20.0; x <= 20.0; x += 0.25)
    for (double h = -0.9; h <= 3.0; h += 0.25) {
      PointT p;
      p.x = float(x);
      p.y = 6.0f;
      p.z = float(h);
      walls.push_back(p);
    }
  const FloorDetection f = FloorDetector().detect(walls);
  EXPECT_FALSE(f.found);
  EXPECT_FALSE(f.reason.empty());
  const FloorDetection empty = FloorDetector().detect(PointCloud());
  EXPECT_FALSE(empty.found);
  EXPECT_NE(empty.reason.find("0 points"), std::string::npos) << empty.reason;
}

TEST(FloorHealth, WarnsOnceWhenTheFloorIsLostAndOnceWhenItIsBack) {
  FloorHealth health(3);
  FloorDetection none;
  none.reason = "only 5 points in the floor band";
  FloorDetection found;
  found.found = true;
  int messages = 0;
  for (uint64_t k = 0; k < 10; ++k) messages += !health.update(k, none).empty();
  EXPECT_EQ(messages, 1);
  const std::string back = health.update(10, found);
  EXPECT_NE(back.find("found again"), std::string::npos) << back;
  EXPECT_TRUE(health.update(11, found).empty());
  EXPECT_EQ(health.found(), 2u);
  EXPECT_EQ(health.missing(), 10u);
  EXPECT_EQ(health.warnings(), 1u);
}

namespace {

/// Base_link 0.93 m above a road that climbs at `slope` along x; keyframe i at x = 2i.
Eigen::Isometry3d truePose(int i, double slope) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(-slope, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const double x = 2.0 * i;
  t.translation() =
      Eigen::Vector3d(x, 0.0, std::tan(slope) * x) + t.linear() * Eigen::Vector3d(0.0, 0.0, 0.93);
  return t;
}

/// The road plane in base_link of a keyframe standing on it: level, 0.93 m below.
const Eigen::Vector4d kFloorUnder(0.0, 0.0, 1.0, 0.93);

/// Keyframe i (2 m apart, a good match) at the given odometry pose.
KeyframeInput keyframeAt(int i, const Eigen::Isometry3d& odom_pose) {
  KeyframeInput kf;
  kf.id = uint64_t(i);
  kf.stamp = 1.0 + i;
  kf.odom_pose = odom_pose;
  kf.accum_distance = 2.0 * i;
  kf.odom_fitness = 0.05;
  return kf;
}

/// Keyframes along a 2 deg climb whose odometry adds 1 cm of height per step (the KITTI elevation
/// bias pattern), with or without floors; returns the final height error [m].
double finalHeightError(bool floors, bool floor_edges = true, double floor_distance_std = -1.0) {
  const double slope = 2.0 * kDeg;
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = true;
  params.floor.floor_edges = floor_edges;
  if (floor_distance_std > 0.0) params.floor.floor_distance_std = floor_distance_std;
  GraphBackend backend(params);
  Eigen::Isometry3d odom = truePose(0, slope);
  for (int i = 0; i < 40; ++i) {
    if (i > 0) {
      Eigen::Isometry3d step = truePose(i - 1, slope).inverse() * truePose(i, slope);
      step.translation().z() += 0.01;
      odom = odom * step;
    }
    KeyframeInput kf = keyframeAt(i, odom);
    if (floors && i % 2 == 0) kf.floor = kFloorUnder;  // half arrive with the keyframe ...
    backend.addKeyframe(kf);
    if (floors && i % 2 == 1) backend.addFloor(uint64_t(i), kFloorUnder);  // ... half later
  }
  backend.update(true);
  const Trajectory t = backend.trajectory();
  const Eigen::Isometry3d first = t.front().pose, last = t.back().pose;
  // Relative to the first keyframe (fixed where odometry started).
  const Eigen::Vector3d truth = (truePose(0, slope).inverse() * truePose(39, slope)).translation();
  return ((first.inverse() * last).translation() - truth).z();
}

}  // namespace

TEST(FloorEdges, TieTheHeightOfConsecutiveKeyframesOnASlope) {
  const double without = finalHeightError(false), off = finalHeightError(true, false),
               with = finalHeightError(true), sharp = finalHeightError(true, true, 0.003);
  std::printf(
      "[floor] height error after 78 m: no floors %.3f m, floor_edges off %.3f m, with "
      "floor edges %.3f m, with 3 mm floors %.3f m\n",
      without, off, with, sharp);
  EXPECT_NEAR(without, 0.39, 0.02);  // 39 steps x 1 cm
  EXPECT_NEAR(off, without, 1e-6);
  // The odometry's own vertical deviation here is ~1 cm per step: default floors (2 cm) pull by
  // their weight, precise floors all the way.
  EXPECT_LT(std::abs(with), 0.92 * std::abs(without));
  EXPECT_LT(std::abs(sharp), 0.2 * std::abs(without));
}

TEST(FloorEdges, ASlopeChangeIsNotTied) {
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = true;
  GraphBackend backend(params);
  // Flat for 5 keyframes, then a 4 deg ramp: the floor bends between keyframes 4 and 5.
  for (int i = 0; i < 10; ++i) {
    KeyframeInput kf = keyframeAt(i, truePose(i, i < 5 ? 0.0 : 4.0 * kDeg));
    kf.floor = kFloorUnder;
    backend.addKeyframe(kf);
  }
  const BackendUpdateReport report = backend.update(true);
  EXPECT_EQ(report.floor_edges, 8u);
  EXPECT_EQ(report.floor_slope_changes, 1u);
  const PoseGraph graph = backend.graphSnapshot();
  const std::vector<int> edges = graph.edgeIds(0, 0, EdgeType::kSE3PlanePair);
  ASSERT_EQ(edges.size(), 8u);
  EXPECT_GT(graph.edge(edges[0])->information(0, 0), 1e3);  // no IMU: the normal is evidence
}

TEST(FloorEdges, WithAnImuAttitudeTheyTieTheHeightOnly) {
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = true;
  GraphBackend backend(params);
  for (int i = 0; i < 3; ++i) {
    KeyframeInput kf = keyframeAt(i, truePose(i, 0.0));
    kf.floor = kFloorUnder;
    kf.gravity_roll_pitch = Eigen::Vector2d::Zero();
    backend.addKeyframe(kf);
  }
  backend.update(true);
  const PoseGraph graph = backend.graphSnapshot();
  const std::vector<int> edges = graph.edgeIds(0, 0, EdgeType::kSE3PlanePair);
  ASSERT_EQ(edges.size(), 2u);
  const Eigen::MatrixXd info = graph.edge(edges[0])->information;
  EXPECT_LT(info(0, 0), 1e-6);
  EXPECT_NEAR(info(2, 2), 0.5 / (0.02 * 0.02), 1e-6);
}

TEST(PlanePairEdge, ZeroAtConsistentPosesAndRejectsAZeroNormal) {
  PoseGraph graph;
  const Eigen::Isometry3d a = truePose(0, 3.0 * kDeg), b = truePose(1, 3.0 * kDeg);
  graph.addVertexSE3(0, a, true);
  graph.addVertexSE3(1, b);
  const int e =
      graph.addEdgeSE3PlanePair(0, 1, kFloorUnder, kFloorUnder, Eigen::Matrix3d::Identity() * 1e4);
  ASSERT_GE(e, 0) << graph.lastError();
  EXPECT_LT(graph.chi2(), 1e-12);
  EXPECT_LT(graph.addEdgeSE3PlanePair(0, 1, Eigen::Vector4d::Zero(), kFloorUnder,
                                      Eigen::Matrix3d::Identity()),
            0);
  // Lift the second pose 10 cm above the plane: the edge sees exactly that.
  Eigen::Isometry3d lifted = b;
  lifted.translation() += b.linear() * Eigen::Vector3d(0.0, 0.0, 0.1);
  graph.setVertexSE3(1, lifted);
  EXPECT_NEAR(graph.chi2(), 1e4 * 0.1 * 0.1, 1e-6);
}
