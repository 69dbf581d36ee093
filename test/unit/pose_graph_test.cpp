// PoseGraph: exact optima, optimisation levels and the two-phase scheme, fixed vertices, mixed
// SE3–SE2 edges, priors, point edges, robust kernels, incremental edits and covariances.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam {
namespace {

Eigen::Isometry3d makeSE3(double x, double y, double z, double roll, double pitch, double yaw) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  t.translation() << x, y, z;
  return t;
}

double se3Distance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  const Eigen::Isometry3d d = a.inverse() * b;
  return d.translation().norm() + Eigen::AngleAxisd(d.linear()).angle();
}

double se2Distance(const Pose2& a, const Pose2& b) {
  return std::hypot(a.x - b.x, a.y - b.y) + std::abs(wrapAngle(a.theta - b.theta));
}

bool sameBits(const PoseGraph& a, const PoseGraph& b, int id) {
  const auto& va = a.vertices().at(id).x;
  const auto& vb = b.vertices().at(id).x;
  return std::memcmp(va.data(), vb.data(), sizeof(double) * va.size()) == 0;
}

Matrix6d se3Information(double translation, double rotation) {
  Matrix6d info = Matrix6d::Identity();
  info.topLeftCorner<3, 3>() *= translation;
  info.bottomRightCorner<3, 3>() *= rotation;
  return info;
}

// A closed 3D loop (a tilted ellipse with a climb) with exact odometry and two loop closures.
std::vector<Eigen::Isometry3d> helixTruth(int n) {
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    poses.push_back(makeSE3(10.0 * std::cos(a), 6.0 * std::sin(a), 0.5 * std::sin(2 * a),
                            0.05 * std::sin(a), 0.03 * std::cos(a), a + M_PI / 2));
  }
  return poses;
}

TEST(PoseGraph, NoiseFreeSE3LoopConvergesToExactOptimum) {
  const int n = 24;
  const auto truth = helixTruth(n);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.2);
  for (bool analytic : {true, false}) {
    PoseGraph g;
    for (int i = 0; i < n; ++i) {
      const Eigen::Isometry3d start =
          i == 0 ? truth[0]
                 : truth[i] * makeSE3(noise(rng), noise(rng), noise(rng), 0.2 * noise(rng),
                                      0.2 * noise(rng), noise(rng));
      ASSERT_TRUE(g.addVertexSE3(i, start, i == 0));
    }
    for (int i = 0; i < n; ++i) {
      const int j = (i + 1) % n;
      ASSERT_GE(g.addEdgeSE3(i, j, truth[i].inverse() * truth[j], se3Information(100, 400)), 0);
    }
    ASSERT_GE(g.addEdgeSE3(3, 15, truth[3].inverse() * truth[15], se3Information(50, 200)), 0);
    OptimizerOptions options;
    options.analytic_jacobians = analytic;
    options.function_tolerance = 1e-12;
    options.parameter_tolerance = 1e-12;
    const OptimizationResult r = g.optimize(0, options);
    EXPECT_TRUE(r.success) << r.message;
    EXPECT_GT(r.initial_chi2, 100.0);
    EXPECT_LT(r.final_chi2, 1e-10) << "analytic=" << analytic;
    EXPECT_NEAR(g.chi2(), r.final_chi2, 1e-12);
    for (int i = 0; i < n; ++i) EXPECT_LT(se3Distance(*g.vertexSE3(i), truth[i]), 1e-6) << i;
  }
}

TEST(PoseGraph, AutoSolvesSmallProblemsWithEigenAndLargerOnesWithSuiteSparse) {
  // 23 free vertices: below auto_eigen_max_free_vertices Eigen's simplicial Cholesky (faster on
  // windows and 1.5 km drives), above it SuiteSparse's supernodal one; both reach the optimum.
  const int n = 24;
  const auto truth = helixTruth(n);
  struct Case {
    SparseLibrary library;
    int eigen_bound;
    std::string expected;
  };
  for (const Case& c : {Case{SparseLibrary::kAuto, 2000, "EIGEN_SPARSE"},
                        Case{SparseLibrary::kAuto, 22, "SUITE_SPARSE"},
                        Case{SparseLibrary::kAuto, 23, "EIGEN_SPARSE"},
                        Case{SparseLibrary::kSuiteSparse, 2000, "SUITE_SPARSE"},
                        Case{SparseLibrary::kEigenSparse, 0, "EIGEN_SPARSE"}}) {
    PoseGraph g;
    for (int i = 0; i < n; ++i)
      ASSERT_TRUE(
          g.addVertexSE3(i, truth[i] * makeSE3(0.1 * (i % 3), -0.1, 0.05, 0, 0, 0.02 * i), i == 0));
    for (int i = 0; i < n; ++i)
      ASSERT_GE(g.addEdgeSE3(i, (i + 1) % n, truth[i].inverse() * truth[(i + 1) % n],
                             se3Information(100, 400)),
                0);
    OptimizerOptions options;
    options.sparse_library = c.library;
    options.auto_eigen_max_free_vertices = c.eigen_bound;
    options.function_tolerance = options.parameter_tolerance = 1e-12;
    const OptimizationResult r = g.optimize(0, options);
    EXPECT_NE(r.linear_solver.find(c.expected), std::string::npos)
        << r.linear_solver << " with bound " << c.eigen_bound;
    EXPECT_LT(r.final_chi2, 1e-10) << r.linear_solver;
  }
}

TEST(PoseGraph, NoiseFreeSE2LoopConvergesToExactOptimum) {
  const int n = 30;
  std::vector<Pose2> truth;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    truth.emplace_back(8.0 * std::cos(a), 8.0 * std::sin(a), wrapAngle(a + M_PI / 2));
  }
  PoseGraph g;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (int i = 0; i < n; ++i) {
    const Pose2 start = i == 0 ? truth[0]
                               : Pose2(truth[i].x + noise(rng), truth[i].y + noise(rng),
                                       truth[i].theta + noise(rng));
    ASSERT_TRUE(g.addVertexSE2(i, start, i == 0));
  }
  const Eigen::Matrix3d info = Eigen::Vector3d(50, 80, 300).asDiagonal();
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    ASSERT_GE(g.addEdgeSE2(i, j, truth[i].inverse() * truth[j], info), 0);
  }
  OptimizerOptions options;
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  const OptimizationResult r = g.optimize(0, options);
  EXPECT_EQ(r.termination, TerminationReason::kConverged) << r.message;
  EXPECT_LT(r.final_chi2, 1e-10);
  for (int i = 0; i < n; ++i) EXPECT_LT(se2Distance(*g.vertexSE2(i), truth[i]), 1e-6) << i;
}

// Robot keyframes (SE3, odometry at level 0) observing buildings (SE2, level 1) that also carry
// an OSM prior (level 1), as in the two-phase scheme of the OSM thesis §3.4.
struct RobotBuildingScene {
  PoseGraph graph;
  std::vector<Eigen::Isometry3d> robot_truth;
  std::vector<Pose2> building_truth;
  std::vector<int> robots, buildings;
};

RobotBuildingScene makeRobotBuildingScene() {
  RobotBuildingScene s;
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (int i = 0; i < 10; ++i) {
    s.robot_truth.push_back(makeSE3(3.0 * i, 0.2 * i * i / 10.0, 0.0, 0.0, 0.0, 0.04 * i));
    const Eigen::Isometry3d start =
        i == 0 ? s.robot_truth[0]
               : s.robot_truth[i] * makeSE3(noise(rng), noise(rng), 0, 0, 0, 0.3 * noise(rng));
    s.graph.addVertexSE3(i, start, i == 0);
    s.robots.push_back(i);
  }
  for (int i = 0; i + 1 < 10; ++i) {
    s.graph.addEdgeSE3(i, i + 1, s.robot_truth[i].inverse() * s.robot_truth[i + 1],
                       se3Information(100, 1000), {0, {}});
  }
  for (int b = 0; b < 4; ++b) {
    const int id = 100 + b;
    s.building_truth.emplace_back(7.0 * b + 2.0, 12.0 * (b % 2 ? 1 : -1), 0.3 * b);
    const Pose2& t = s.building_truth.back();
    s.graph.addVertexSE2(id, Pose2(t.x + 1.5, t.y - 1.0, t.theta + 0.2));
    s.buildings.push_back(id);
    // The OSM prior is off by a metre; the robot observations are exact and stronger.
    s.graph.addPriorSE2(id, Pose2(t.x + 1.0, t.y, t.theta), Eigen::Matrix3d::Identity(), {1, {}});
    for (int r = 2 * b; r < 2 * b + 3; ++r) {
      const Pose2 z = planarPose(s.robot_truth[r]).inverse() * t;
      s.graph.addEdgeSE3SE2(r, id, z, Eigen::Vector3d(400, 400, 2000).asDiagonal(),
                            {1, RobustKernel::huber(5.0)});
    }
  }
  return s;
}

TEST(PoseGraph, LevelZeroLeavesLevelOneVerticesUntouched) {
  RobotBuildingScene s = makeRobotBuildingScene();
  const PoseGraph before = s.graph;
  const std::vector<int> active = s.graph.activeVertexIds(0);
  EXPECT_EQ(active, s.robots);
  const OptimizationResult r = s.graph.optimize(0);
  EXPECT_EQ(r.num_edges, 9);
  EXPECT_EQ(r.num_vertices, 10);
  EXPECT_LT(r.final_chi2, 1e-8);
  for (int id : s.buildings) EXPECT_TRUE(sameBits(before, s.graph, id)) << id;
  for (int i = 1; i < 10; ++i) {
    EXPECT_FALSE(sameBits(before, s.graph, i));
    EXPECT_LT(se3Distance(*s.graph.vertexSE3(i), s.robot_truth[i]), 1e-5);
  }
}

TEST(PoseGraph, TwoPhaseMovesOnlyBuildingsInPhaseTwo) {
  RobotBuildingScene s = makeRobotBuildingScene();
  s.graph.optimize(0);
  const PoseGraph after_phase1 = s.graph;
  for (int id : s.robots) s.graph.setFixed(id, true);
  const OptimizationResult r = s.graph.optimize(1);
  EXPECT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.num_edges, 9 + 4 + 12);
  EXPECT_LT(r.final_chi2, r.initial_chi2);
  for (int id : s.robots) EXPECT_TRUE(sameBits(after_phase1, s.graph, id)) << id;
  for (size_t b = 0; b < s.buildings.size(); ++b) {
    EXPECT_FALSE(sameBits(after_phase1, s.graph, s.buildings[b]));
    // Exact observations (information 400–2000) against a 1 m prior (information 1): the
    // building lands within a few mm of the truth, far from both its start and the prior.
    const Pose2 est = *s.graph.vertexSE2(s.buildings[b]);
    EXPECT_LT(se2Distance(est, s.building_truth[b]), 0.01) << b;
  }
}

TEST(PoseGraph, FixedVerticesAreBitwiseUnchanged) {
  RobotBuildingScene s = makeRobotBuildingScene();
  s.graph.setFixed(5, true);
  s.graph.setFixed(101, true);
  const PoseGraph before = s.graph;
  const OptimizationResult r = s.graph.optimize(1);
  EXPECT_TRUE(r.success);
  EXPECT_EQ(r.num_fixed_vertices, 3);
  for (int id : {0, 5, 101}) EXPECT_TRUE(sameBits(before, s.graph, id)) << id;
  EXPECT_FALSE(sameBits(before, s.graph, 4));
  EXPECT_FALSE(sameBits(before, s.graph, 100));
}

TEST(PoseGraph, MixedSE3SE2RecoversKnownPlanarTransform) {
  const Eigen::Isometry3d robot_truth = makeSE3(4.0, -2.0, 1.2, 0.03, -0.02, 0.7);
  const Pose2 building_truth(15.0, 6.0, -0.4);
  const Pose2 z = planarPose(robot_truth).inverse() * building_truth;
  const Eigen::Matrix3d info = Eigen::Vector3d(100, 100, 500).asDiagonal();

  // (a) The robot has a full prior: the building is recovered from a perturbed start.
  PoseGraph a;
  a.addVertexSE3(0, robot_truth * makeSE3(0.5, -0.4, 0.1, 0.01, 0.02, 0.2));
  a.addVertexSE2(1, Pose2(13.0, 8.0, 0.3));
  a.addPriorSE3(0, robot_truth, se3Information(1e4, 1e5));
  ASSERT_GE(a.addEdgeSE3SE2(0, 1, z, info), 0);
  OptimizerOptions tight;
  tight.function_tolerance = 1e-14;
  tight.parameter_tolerance = 1e-14;
  EXPECT_LT(a.optimize(0, tight).final_chi2, 1e-12);
  EXPECT_LT(se3Distance(*a.vertexSE3(0), robot_truth), 1e-6);
  EXPECT_LT(se2Distance(*a.vertexSE2(1), building_truth), 1e-6);

  // (b) The building is fixed: the robot's x, y and yaw follow from the edge alone (its z comes
  // from an xyz prior with zero information in x and y).
  PoseGraph b;
  b.addVertexSE3(0, robot_truth * makeSE3(-1.0, 0.8, 0.3, 0.0, 0.0, -0.35));
  b.addVertexSE2(1, building_truth, true);
  ASSERT_GE(b.addEdgeSE3SE2(0, 1, z, info), 0);
  ASSERT_GE(b.addPriorSE3XYZ(0, robot_truth.translation(), Eigen::Vector3d(0, 0, 10).asDiagonal()),
            0);
  EXPECT_LT(b.optimize(0, tight).final_chi2, 1e-12);
  const Pose2 planar = planarPose(*b.vertexSE3(0));
  EXPECT_LT(se2Distance(planar, planarPose(robot_truth)), 1e-6);
  EXPECT_NEAR(b.vertexSE3(0)->translation().z(), 1.2, 1e-6);
}

TEST(PoseGraph, WallOnlyEdgesLeaveTheBuildingWhereItsPriorIsAlongTheWall) {
  // Two matches of one facade (along the building's x axis) that disagree by 0.3 m across it and
  // by 2.3 deg in heading. Each informs only across the wall. In the measurements' axes their
  // free directions would cross 7.5 m along the wall and drag the building there.
  PoseGraph g;
  g.addVertexSE3(0, Eigen::Isometry3d::Identity(), true);
  const Pose2 prior(10.0, 5.0, 0.0);
  g.addVertexSE2(1, prior);
  Eigen::Matrix3d wall_info = Eigen::Vector3d(1e-4, 100.0, 1000.0).asDiagonal();
  ASSERT_GE(g.addEdgeSE3SE2(0, 1, Pose2(10.0, 5.3, 0.04), wall_info), 0);
  ASSERT_GE(g.addEdgeSE3SE2(0, 1, Pose2(10.0, 5.0, 0.0), wall_info), 0);
  ASSERT_GE(g.addPriorSE2(1, prior, Eigen::Vector3d(0.04, 0.04, 1.0).asDiagonal()), 0);
  g.optimize(0);
  const Pose2 b = *g.vertexSE2(1);
  EXPECT_NEAR(b.x, 10.0, 0.1) << "slid along its wall";
  EXPECT_NEAR(b.y, 5.15, 0.05);
  EXPECT_NEAR(b.theta, 0.02, 0.005);
}

TEST(PoseGraph, PointOnLineEdgesConstrainOnlyTheDistanceFromTheLine) {
  // Building 2 (fixed, turned 90 deg) has the wall x = 5 in its frame: the world line y = 5.
  // Building 1's corner at its origin starts 3 m off it and its prior is weak.
  PoseGraph g;
  g.addVertexSE2(1, Pose2(3.0, 2.0, 0.3));
  g.addVertexSE2(2, Pose2(20.0, 0.0, M_PI / 2), true);
  ASSERT_GE(g.addPriorSE2(1, Pose2(3.0, 2.0, 0.3), Eigen::Vector3d(1, 1, 1).asDiagonal()), 0);
  const int edge =
      g.addEdgeSE2PointOnLine(1, 2, Eigen::Vector2d::Zero(), Eigen::Vector2d(2, 0), 10.0, 1e4);
  ASSERT_GE(edge, 0) << g.lastError();
  EXPECT_EQ(g.edge(edge)->measurement[4], 5.0) << "normal and offset are normalised together";
  g.optimize();
  const Pose2 moved = *g.vertexSE2(1);
  EXPECT_NEAR(moved.y, 5.0, 0.002) << "onto the line";
  EXPECT_NEAR(moved.x, 3.0, 1e-6) << "nothing imposed along it";
  EXPECT_NEAR(moved.theta, 0.3, 1e-6) << "nor on the heading";
  EXPECT_LT(g.addEdgeSE2PointOnLine(1, 2, Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), 1, 1),
            0);
}

TEST(PoseGraph, UnaryPriorsAndPointEdges) {
  PoseGraph g;
  g.addVertexSE3(0, makeSE3(1, 1, 1, 0.1, 0.1, 1.0));
  ASSERT_GE(g.addPriorSE3XY(0, Eigen::Vector2d(5, -3), Eigen::Matrix2d::Identity() * 10), 0);
  ASSERT_GE(g.addPriorSE3Yaw(0, -2.5, 50.0), 0);
  ASSERT_GE(g.addPriorSE3XYZ(0, Eigen::Vector3d(0, 0, 2), Eigen::Vector3d(0, 0, 5).asDiagonal()),
            0);
  // An XY landmark seen from the SE3 pose and from an SE2 pose with a full prior.
  g.addVertexPointXY(1, Eigen::Vector2d(0, 0));
  g.addVertexSE2(2, Pose2(0, 0, 0));
  ASSERT_GE(g.addPriorSE2(2, Pose2(2, 2, M_PI / 2), Eigen::Matrix3d::Identity() * 100), 0);
  const Eigen::Vector2d landmark(4, 1);
  const Pose2 robot_planar(5, -3, -2.5);
  ASSERT_GE(g.addEdgeSE3PointXY(0, 1, robot_planar.inverse().transform(landmark),
                                Eigen::Matrix2d::Identity()),
            0);
  ASSERT_GE(g.addEdgeSE2PointXY(2, 1, Pose2(2, 2, M_PI / 2).inverse().transform(landmark),
                                Eigen::Matrix2d::Identity()),
            0);
  OptimizerOptions tight;
  tight.function_tolerance = 1e-14;
  tight.parameter_tolerance = 1e-14;
  const OptimizationResult r = g.optimize(0, tight);
  EXPECT_LT(r.final_chi2, 1e-12) << r.message;
  EXPECT_LT(se2Distance(planarPose(*g.vertexSE3(0)), robot_planar), 1e-6);
  EXPECT_NEAR(g.vertexSE3(0)->translation().z(), 2.0, 1e-6);
  EXPECT_LT((*g.vertexPointXY(1) - landmark).norm(), 1e-6);
  EXPECT_LT(se2Distance(*g.vertexSE2(2), Pose2(2, 2, M_PI / 2)), 1e-6);
}

// Odometry 0.5 % short on a curved 3D path, two windows of scale, and XY fixes at the true
// positions: the scales absorb the shortfall, so the stiff odometry edges end without error (no
// prior on the scale: the fixes decide it).
TEST(PoseGraph, ScaledOdometryEdgesRecoverTheOdometryScale) {
  const int n = 24;
  const auto truth = helixTruth(n);
  const double odometry_scale = 0.995;
  PoseGraph g;
  ASSERT_TRUE(g.addVertexScale(100, 1.0));
  ASSERT_TRUE(g.addVertexScale(101, 1.0));
  ASSERT_GE(g.addEdgeScaleDifference(100, 101, 0.0, 1.0 / (0.002 * 0.002)), 0);
  for (int i = 0; i < n; ++i) {
    g.addVertexSE3(i, i == 0 ? truth[0] : Eigen::Isometry3d::Identity(), i == 0);
    if (i % 4 == 0)
      g.addPriorSE3XY(i, truth[i].translation().head<2>(), Eigen::Matrix2d::Identity() * 100.0);
  }
  for (int i = 1; i < n; ++i) {
    Eigen::Isometry3d odom = truth[i - 1].inverse() * truth[i];
    odom.translation().head<2>() *= odometry_scale;  // the scale is horizontal
    ASSERT_GE(g.addEdgeSE3Scaled(i - 1, i, i < n / 2 ? 100 : 101, odom, se3Information(1e4, 1e6)),
              0)
        << g.lastError();
  }
  OptimizerOptions tight;
  tight.function_tolerance = 1e-14;
  tight.parameter_tolerance = 1e-14;
  const OptimizationResult r = g.optimize(0, tight);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(*g.vertexScale(100), 1.0 / odometry_scale, 2e-4);
  EXPECT_NEAR(*g.vertexScale(101), 1.0 / odometry_scale, 2e-4);
  for (int i = 0; i < n; ++i) EXPECT_LT(se3Distance(*g.vertexSE3(i), truth[i]), 2e-3) << i;
  // The same graph with the scales held at 1 keeps the odometry's shortfall.
  g.setFixed(100, true);
  g.setFixed(101, true);
  g.setVertexScale(100, 1.0);
  g.setVertexScale(101, 1.0);
  g.optimize(0, tight);
  double worst = 0.0;
  for (int i = 0; i < n; ++i) worst = std::max(worst, se3Distance(*g.vertexSE3(i), truth[i]));
  EXPECT_GT(worst, 0.02);
}

// A LiDAR's elevation bias makes the odometry climb on flat ground (walls seen from nearer look
// lower). The floors hold the height; they must not shrink the scale to undo the climb (session
// 28: a 1.5 km drive without OSM ended with a scale of 0.994 and a 23 % larger ATE).
TEST(PoseGraph, AVerticalOdometryDriftHeldByFloorsLeavesTheScaleAlone) {
  const int n = 40;
  PoseGraph g;
  ASSERT_TRUE(g.addVertexScale(100, 1.0));
  ASSERT_GE(g.addPriorScale(100, 1.0, 1.0 / (0.01 * 0.01)), 0);
  const Eigen::Vector4d floor(0.0, 0.0, 1.0, 1.73);  // flat ground under every keyframe
  for (int i = 0; i < n; ++i) {
    Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
    truth.translation() << 2.0 * i, 0.0, 0.0;
    g.addVertexSE3(i, truth, i == 0);
    if (i == 0) continue;
    Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
    odom.translation() << 2.0, 0.0, 0.02;  // 1 % climb
    ASSERT_GE(g.addEdgeSE3Scaled(i - 1, i, 100, odom, se3Information(1e4, 1e6)), 0);
    ASSERT_GE(g.addEdgeSE3PlanePair(i - 1, i, floor, floor,
                                    Eigen::Vector3d(1e-9, 1e-9, 1250.0).asDiagonal()),
              0);
  }
  ASSERT_TRUE(g.optimize(0).success);
  EXPECT_NEAR(*g.vertexScale(100), 1.0, 1e-4);
  EXPECT_NEAR(g.vertexSE3(n - 1)->translation().x(), 2.0 * (n - 1), 5e-3);
}

TEST(PoseGraph, ScaleEdgesCheckTheirVertices) {
  PoseGraph g;
  g.addVertexSE3(0, Eigen::Isometry3d::Identity());
  g.addVertexSE3(1, Eigen::Isometry3d::Identity());
  g.addVertexScale(2, 1.0);
  EXPECT_FALSE(g.addVertexScale(3, NAN));
  const Eigen::Isometry3d z = Eigen::Isometry3d::Identity();
  EXPECT_LT(g.addEdgeSE3Scaled(0, 1, 1, z, Matrix6d::Identity()), 0);
  EXPECT_NE(g.lastError().find("expected scale"), std::string::npos) << g.lastError();
  EXPECT_LT(g.addEdgeSE3Scaled(0, 0, 2, z, Matrix6d::Identity()), 0);
  EXPECT_NE(g.lastError().find("itself"), std::string::npos);
  EXPECT_LT(g.addPriorScale(0, 1.0, 1.0), 0);
  const int e = g.addEdgeSE3Scaled(0, 1, 2, z, Matrix6d::Identity());
  ASSERT_GE(e, 0);
  EXPECT_EQ(g.edge(e)->vertices, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(g.edgesOfVertex(2), std::vector<int>{e});
  EXPECT_TRUE(g.removeVertex(2));
  EXPECT_EQ(g.numEdges(), 0u);
}

// A straight SE2 corridor with one wrong loop closure (10 m off).
PoseGraph corridorWithOutlier(RobustKernel kernel) {
  PoseGraph g;
  const Eigen::Matrix3d info = Eigen::Vector3d(100, 100, 1000).asDiagonal();
  for (int i = 0; i < 20; ++i) g.addVertexSE2(i, Pose2(i, 0, 0), i == 0);
  for (int i = 0; i + 1 < 20; ++i) g.addEdgeSE2(i, i + 1, Pose2(1, 0, 0), info);
  g.addEdgeSE2(0, 19, Pose2(9, 0, 0), info, {0, kernel});
  return g;
}

TEST(PoseGraph, RobustKernelsLimitAnOutlier) {
  PoseGraph plain = corridorWithOutlier(RobustKernel::none());
  PoseGraph cauchy = corridorWithOutlier(RobustKernel::cauchy(1.0));
  PoseGraph huber = corridorWithOutlier(RobustKernel::huber(1.0));
  plain.optimize();
  cauchy.optimize();
  huber.optimize();
  // Chain stiffness k = 100/19 per m²; the loop (information 100) wants the end at 9 m.
  // Least squares: x = (19 k + 9·100) / (k + 100) = 9.5. Huber (width 1): the loop's ρ grows as
  // 2·√100·(19 − x) − 1, so k·2·(19 − x) = 20 → x = 17.1. Cauchy: the outlier's pull vanishes.
  EXPECT_NEAR(plain.vertexSE2(19)->x, 9.5, 0.01);
  EXPECT_NEAR(huber.vertexSE2(19)->x, 17.1, 0.01);
  EXPECT_NEAR(cauchy.vertexSE2(19)->x, 19.0, 0.05);
}

TEST(PoseGraph, EdgesCanBeAddedAndRemovedBetweenOptimisations) {
  PoseGraph g = corridorWithOutlier(RobustKernel::none());
  const std::vector<int> loops = g.edgeIds(0, INT_MAX, EdgeType::kSE2);
  ASSERT_EQ(loops.size(), 20u);
  const int outlier = loops.back();
  EXPECT_GT(g.optimize().final_chi2, 100.0);
  ASSERT_TRUE(g.removeEdge(outlier));
  EXPECT_FALSE(g.removeEdge(outlier));
  OptimizationResult r = g.optimize();
  EXPECT_LT(r.final_chi2, 1e-10);
  EXPECT_EQ(r.num_edges, 19);
  EXPECT_NEAR(g.vertexSE2(19)->x, 19.0, 1e-5);
  // A correct loop closure added afterwards at a higher level is ignored by level 0.
  const int loop = g.addEdgeSE2(0, 19, Pose2(19, 0, 0), Eigen::Matrix3d::Identity(), {2, {}});
  ASSERT_GE(loop, 0);
  EXPECT_EQ(g.edgeIds(2, 2), std::vector<int>{loop});
  EXPECT_EQ(g.optimize(1).num_edges, 19);
  EXPECT_EQ(g.optimize(2).num_edges, 20);
  EXPECT_TRUE(g.removeVertex(19));
  EXPECT_TRUE(g.edgeIds(2, 2).empty());
  EXPECT_EQ(g.numEdges(), 18u);
}

TEST(PoseGraph, NothingToSolve) {
  PoseGraph g;
  g.addVertexSE2(0, Pose2(1, 2, 3));
  OptimizationResult r = g.optimize();
  EXPECT_EQ(r.termination, TerminationReason::kNothingToSolve);
  EXPECT_TRUE(r.success);
  g.addVertexSE2(1, Pose2(0, 0, 0), true);
  g.setFixed(0, true);
  g.addEdgeSE2(1, 0, Pose2(1, 1, 1), Eigen::Matrix3d::Identity(), {3, {}});
  EXPECT_EQ(g.optimize(2).num_edges, 0);
  r = g.optimize(3);
  EXPECT_EQ(r.termination, TerminationReason::kNothingToSolve);
  EXPECT_NEAR(r.initial_chi2, g.chi2(), 1e-12);
}

TEST(PoseGraph, InvalidInputIsRejectedWithAReason) {
  PoseGraph g;
  g.addVertexSE2(0, Pose2());
  g.addVertexSE3(1, Eigen::Isometry3d::Identity());
  EXPECT_FALSE(g.addVertexSE2(0, Pose2()));
  EXPECT_FALSE(g.addVertexSE2(5, Pose2(NAN, 0, 0)));
  EXPECT_LT(g.addEdgeSE2(0, 7, Pose2(), Eigen::Matrix3d::Identity()), 0);
  EXPECT_NE(g.lastError().find("unknown vertex 7"), std::string::npos);
  EXPECT_LT(g.addEdgeSE2(0, 1, Pose2(), Eigen::Matrix3d::Identity()), 0);
  EXPECT_NE(g.lastError().find("is SE3"), std::string::npos);
  g.addVertexSE2(2, Pose2());
  EXPECT_LT(g.addEdgeSE2(0, 2, Pose2(), -Eigen::Matrix3d::Identity()), 0);
  EXPECT_NE(g.lastError().find("positive semi-definite"), std::string::npos);
  EXPECT_LT(g.addEdgeSE2(0, 2, Pose2(NAN, 0, 0), Eigen::Matrix3d::Identity()), 0);
  EXPECT_LT(g.addEdgeSE2(0, 2, Pose2(), Eigen::Matrix3d::Identity(), {-1, {}}), 0);
  EXPECT_LT(g.addEdgeSE2(0, 2, Pose2(), Eigen::Matrix3d::Identity(), {0, RobustKernel::huber(0)}),
            0);
  EXPECT_EQ(g.numEdges(), 0u);
}

TEST(PoseGraph, MarginalCovarianceMatchesClosedForm) {
  // SE2 chain: fixed origin, one edge with a diagonal information → covariance = Ω⁻¹.
  PoseGraph g;
  g.addVertexSE2(0, Pose2(), true);
  g.addVertexSE2(1, Pose2(2, 0, 0));
  g.addEdgeSE2(0, 1, Pose2(2, 0, 0), Eigen::Vector3d(4, 25, 100).asDiagonal());
  Eigen::MatrixXd cov;
  ASSERT_TRUE(g.marginalCovariance(1, &cov)) << g.lastError();
  EXPECT_TRUE(cov.isApprox(Eigen::Vector3d(0.25, 0.04, 0.01).asDiagonal().toDenseMatrix(), 1e-9))
      << cov;
  ASSERT_TRUE(g.marginalCovariance(0, &cov));
  EXPECT_EQ(cov.norm(), 0.0);

  // SE3 full prior at identity rotation: translation Ω_t⁻¹; the error uses q.vec ≈ δθ/2, so
  // the rotation-vector covariance is 4 Ω_r⁻¹.
  PoseGraph h;
  h.addVertexSE3(0, makeSE3(1, 2, 3, 0, 0, 0));
  Matrix6d info = Matrix6d::Zero();
  info.diagonal() << 1, 4, 16, 100, 400, 1600;
  h.addPriorSE3(0, makeSE3(1, 2, 3, 0, 0, 0), info);
  ASSERT_TRUE(h.marginalCovariance(0, &cov)) << h.lastError();
  Vector6d expected;
  expected << 1, 0.25, 0.0625, 0.04, 0.01, 0.0025;
  EXPECT_TRUE(cov.diagonal().isApprox(expected, 1e-9)) << cov.diagonal().transpose();

  // No gauge: a single relative edge between two free vertices is rank deficient.
  PoseGraph free;
  free.addVertexSE2(0, Pose2());
  free.addVertexSE2(1, Pose2(1, 0, 0));
  free.addEdgeSE2(0, 1, Pose2(1, 0, 0), Eigen::Matrix3d::Identity());
  EXPECT_FALSE(free.marginalCovariance(1, &cov));
  EXPECT_NE(free.lastError().find("rank deficient"), std::string::npos);
}

}  // namespace
}  // namespace osm_graph_slam
