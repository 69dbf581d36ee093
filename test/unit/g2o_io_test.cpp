// .g2o reading and writing: exact round trip, odometry-chain initialisation of edge-only files,
// and errors with line numbers on malformed files (the output graph is left untouched).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "osm_graph_slam/graph/g2o_io.h"

namespace osm_graph_slam {
namespace {

G2oReadResult readText(const std::string& text, PoseGraph* g) {
  std::istringstream in(text);
  return readG2o(in, g);
}

PoseGraph mixedGraph() {
  PoseGraph g;
  g.addVertexSE2(0, Pose2(0, 0, 0), true);
  g.addVertexSE2(1, Pose2(1.25, -0.5, 0.3));
  g.addVertexSE2(2, Pose2(2.5, 0.125, -3.0));
  g.addVertexPointXY(7, Eigen::Vector2d(3.0, 4.0));
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  b.translation() << 1.0 / 3.0, -2.0, 0.1;
  g.addVertexSE3(10, a);
  g.addVertexSE3(11, b);
  Eigen::Matrix3d info3;
  info3 << 10, 1, 0.5, 1, 20, 0.25, 0.5, 0.25, 300;
  g.addEdgeSE2(0, 1, Pose2(1.2, -0.4, 0.31), info3);
  g.addEdgeSE2(1, 2, Pose2(1.0 / 7.0, 0.6, 2.9), info3 * 2);
  g.addEdgeSE2PointXY(2, 7, Eigen::Vector2d(0.5, -1.5), Eigen::Matrix2d::Identity() * 3);
  g.addPriorSE2(0, Pose2(0.01, 0.02, 0.03), info3);
  Matrix6d info6 = Matrix6d::Identity() * 50;
  info6(0, 4) = info6(4, 0) = 0.5;
  g.addEdgeSE3(10, 11, b, info6);
  g.addPriorSE3XYZ(11, Eigen::Vector3d(1, 2, 3), Eigen::Matrix3d::Identity());  // not in g2o
  return g;
}

TEST(G2oIo, RoundTripReproducesTheGraph) {
  const PoseGraph g = mixedGraph();
  const std::string path =
      (std::filesystem::temp_directory_path() / "ogs_g2o_round_trip.g2o").string();
  const G2oWriteResult w = writeG2o(g, path);
  ASSERT_TRUE(w.ok) << w.message;
  EXPECT_EQ(w.num_vertices, 6);
  EXPECT_EQ(w.num_edges, 5);
  EXPECT_EQ(w.num_skipped_edges, 1);

  PoseGraph back;
  const G2oReadResult r = readG2o(path, &back);
  std::filesystem::remove(path);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.num_fixed, 1);
  EXPECT_EQ(r.num_initialised, 0);
  ASSERT_EQ(back.vertexIds(), g.vertexIds());
  for (int id : g.vertexIds()) {
    EXPECT_EQ(back.vertexType(id), g.vertexType(id));
    EXPECT_EQ(back.isFixed(id), g.isFixed(id));
    for (size_t k = 0; k < 7; ++k) {
      EXPECT_NEAR(back.vertices().at(id).x[k], g.vertices().at(id).x[k], 1e-15) << id;
    }
  }
  ASSERT_EQ(back.numEdges(), 5u);
  // Edges come back in file order: the g2o-expressible edges of g, in id order.
  std::vector<EdgeInfo> original;
  for (int id : g.edgeIds()) {
    if (g.edge(id)->type != EdgeType::kPriorSE3XYZ) original.push_back(*g.edge(id));
  }
  const std::vector<int> back_ids = back.edgeIds();
  for (size_t i = 0; i < original.size(); ++i) {
    const EdgeInfo e = *back.edge(back_ids[i]);
    EXPECT_EQ(e.type, original[i].type);
    EXPECT_EQ(e.vertices, original[i].vertices);
    EXPECT_LT((e.measurement - original[i].measurement).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_EQ(e.information, original[i].information);
  }
  // Same graph, same χ² (the SE3 prior is not part of the written file).
  PoseGraph without_prior = g;
  without_prior.removeEdge(g.edgeIds(0, INT_MAX, EdgeType::kPriorSE3XYZ).front());
  EXPECT_NEAR(back.chi2(), without_prior.chi2(), 1e-9 * without_prior.chi2());
}

// g2o has no scale: a scaled SE3 edge is written as the SE3 edge it is at today's scale (its
// horizontal translation scaled), the scale vertex and its prior are left out, and the file's χ²
// is the graph's odometry χ².
TEST(G2oIo, ScaledSE3EdgeIsWrittenAtTheEstimatedScale) {
  PoseGraph g;
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.translation() << 2.0, 0.5, 0.3;
  g.addVertexSE3(0, Eigen::Isometry3d::Identity(), true);
  g.addVertexSE3(1, b);
  g.addVertexScale(5, 1.004);
  g.addPriorScale(5, 1.0, 1e4);
  Eigen::Isometry3d z = b;
  z.translation() *= 0.99;
  ASSERT_GE(g.addEdgeSE3Scaled(0, 1, 5, z, Matrix6d::Identity() * 100), 0);
  std::ostringstream out;
  const G2oWriteResult w = writeG2o(g, out);
  ASSERT_TRUE(w.ok);
  EXPECT_EQ(w.num_vertices, 2);
  EXPECT_EQ(w.num_skipped_vertices, 1);
  EXPECT_EQ(w.num_edges, 1);
  EXPECT_EQ(w.num_skipped_edges, 1);
  PoseGraph back;
  ASSERT_TRUE(readText(out.str(), &back).ok) << out.str();
  const EdgeInfo e = *back.edge(back.edgeIds().front());
  EXPECT_EQ(e.type, EdgeType::kSE3);
  EXPECT_EQ(e.vertices, (std::vector<int>{0, 1}));
  EXPECT_NEAR(e.measurement[0], 2.0 * 0.99 * 1.004, 1e-12);
  EXPECT_NEAR(e.measurement[1], 0.5 * 0.99 * 1.004, 1e-12);
  EXPECT_NEAR(e.measurement[2], 0.3 * 0.99, 1e-12);  // the scale is horizontal
  PoseGraph odometry_only = g;
  odometry_only.removeEdge(g.edgeIds(0, INT_MAX, EdgeType::kPriorScale).front());
  EXPECT_NEAR(back.chi2(), odometry_only.chi2(), 1e-9);
}

TEST(G2oIo, EdgeOnlyFileIsInitialisedFromTheOdometryChain) {
  const std::string text =
      "# M3500-style: edges only\n"
      "EDGE_SE2 0 1 1 0 1.5707963267948966 1 0 0 1 0 1\n"
      "EDGE_SE2 1 2 2 0 1.5707963267948966 1 0 0 1 0 1\n"
      "\n"
      "EDGE_SE2 3 0 0.5 0.5 0 1 0 0 1 0 1\n"  // loop closure listed before the odometry edge
      "EDGE_SE2 2 3 1 0 0 1 0 0 1 0 1\n";
  PoseGraph g;
  const G2oReadResult r = readText(text, &g);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.num_initialised, 4);
  EXPECT_EQ(g.numEdges(), 4u);
  // 0 at the origin; 1 = (1, 0, 90°); 2 = 1 ∘ (2, 0, 90°) = (1, 2, 180°); 3 = 2 ∘ (1, 0, 0).
  const Pose2 p1 = *g.vertexSE2(1), p2 = *g.vertexSE2(2), p3 = *g.vertexSE2(3);
  EXPECT_NEAR(p1.x, 1.0, 1e-12);
  EXPECT_NEAR(p1.theta, M_PI / 2, 1e-12);
  EXPECT_NEAR(p2.x, 1.0, 1e-12);
  EXPECT_NEAR(p2.y, 2.0, 1e-12);
  EXPECT_NEAR(std::abs(p2.theta), M_PI, 1e-12);
  EXPECT_NEAR(p3.x, 0.0, 1e-12);
  EXPECT_NEAR(p3.y, 2.0, 1e-12);

  // SE3 chain, declared vertex in the middle, chain extends backwards and forwards.
  const std::string text3 =
      "VERTEX_SE3:QUAT 5 10 0 0 0 0 0 1\n"
      "EDGE_SE3:QUAT 4 5 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n"
      "EDGE_SE3:QUAT 5 6 0 2 0 0 0 0.7071067811865476 0.7071067811865476 "
      "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n"
      "EDGE_SE3:QUAT 6 7 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  PoseGraph g3;
  const G2oReadResult r3 = readText(text3, &g3);
  ASSERT_TRUE(r3.ok) << r3.message;
  EXPECT_EQ(r3.num_initialised, 3);
  EXPECT_TRUE(g3.vertexSE3(4)->translation().isApprox(Eigen::Vector3d(9, 0, 0)));
  EXPECT_TRUE(g3.vertexSE3(7)->translation().isApprox(Eigen::Vector3d(10, 3, 0)))
      << g3.vertexSE3(7)->translation().transpose();
  EXPECT_LT(g3.chi2(), 1e-20);
}

struct BadFile {
  std::string text;
  int line;
  std::string fragment;
};

TEST(G2oIo, MalformedFilesGiveLineNumberedErrorsAndKeepTheGraph) {
  const std::string ok2 = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n";
  const std::vector<BadFile> cases = {
      {ok2 + "EDGE_SE7 0 1 1 0 0 1 0 0 1 0 1\n", 3, "unknown tag 'EDGE_SE7'"},
      {ok2 + "EDGE_SE2 0 1 1 0 0 1 0 0 1\n", 3, "expects 11 values, got 9"},
      {ok2 + "EDGE_SE2 0 1 1 zero 0 1 0 0 1 0 1\n", 3, "'zero' is not a finite number"},
      {ok2 + "EDGE_SE2 0 1 1 0 nan 1 0 0 1 0 1\n", 3, "'nan' is not a finite number"},
      {ok2 + "EDGE_SE2 0 x 1 0 0 1 0 0 1 0 1\n", 3, "'x' is not a vertex id"},
      {ok2 + "VERTEX_SE2 1 2 2 2\n", 3, "declared twice"},
      {ok2 + "\n\nEDGE_SE2 0 1 1 0 0 -1 0 0 1 0 1\n", 5, "positive semi-definite"},
      {ok2 + "VERTEX_SE3:QUAT 2 0 0 0 0 0 0 1\nEDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\n", 4,
       "vertex 2 is SE3 but the edge needs SE2"},
      {ok2 + "FIX 9\n", 3, "FIX: unknown vertex 9"},
      {ok2 + "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 5 6 1 0 0 1 0 0 1 0 1\n", 4,
       "not connected"},
      {ok2 + "VERTEX_SE3:QUAT 3 0 0 0 0 0 0 0\n", 3, "quaternion"},
      {"", 0, "no vertex and no edge"},
  };
  for (const BadFile& c : cases) {
    PoseGraph g;
    g.addVertexSE2(42, Pose2(1, 2, 3));
    const G2oReadResult r = readText(c.text, &g);
    EXPECT_FALSE(r.ok) << c.text;
    EXPECT_EQ(r.line, c.line) << r.message;
    EXPECT_NE(r.message.find(c.fragment), std::string::npos) << r.message;
    if (c.line > 0) {
      EXPECT_EQ(r.message.rfind("line " + std::to_string(c.line) + ": ", 0), 0u) << r.message;
    }
    EXPECT_EQ(g.vertexIds(), std::vector<int>{42});  // untouched
  }
  PoseGraph g;
  const G2oReadResult missing = readG2o("/nonexistent/dir/file.g2o", &g);
  EXPECT_FALSE(missing.ok);
  EXPECT_NE(missing.message.find("cannot open"), std::string::npos);
  EXPECT_FALSE(writeG2o(mixedGraph(), "/nonexistent/dir/out.g2o").ok);
}

// Issue 22: cubicle.g2o (a public SE3 dataset) has an edge with an indefinite information matrix.
// By default it is refused (with the smallest eigenvalue and the way on); with
// repair_information it is read with the nearest positive semi-definite matrix, and counted.
TEST(G2oIo, IndefiniteInformationIsRefusedOrRepairedOnRequest) {
  // Upper triangle of a 6x6 information: diagonal 100 (translation) and 400 (rotation), with an
  // x-y coupling of 150 > 100 that makes the top-left 2x2 block indefinite (eigenvalues 250, -50).
  const std::string indefinite = "100 150 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400";
  const std::string good = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400";
  const std::string text =
      "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n"
      "VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n"
      "VERTEX_SE3:QUAT 2 2 0 0 0 0 0 1\n"
      "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 " +
      good +
      "\n"
      "EDGE_SE3:QUAT 1 2 1 0 0 0 0 0 1 " +
      indefinite +
      "\n"
      "EDGE_SE3:QUAT 0 2 2 0 0 0 0 0 1 " +
      indefinite + "\n";
  PoseGraph refused;
  const G2oReadResult strict = readText(text, &refused);
  EXPECT_FALSE(strict.ok);
  EXPECT_EQ(strict.line, 5);
  EXPECT_NE(strict.message.find("positive semi-definite"), std::string::npos) << strict.message;
  EXPECT_NE(strict.message.find("smallest eigenvalue -50"), std::string::npos) << strict.message;
  EXPECT_NE(strict.message.find("repair-information"), std::string::npos) << strict.message;
  EXPECT_EQ(refused.numVertices(), 0u);

  PoseGraph repaired;
  G2oReadOptions options;
  options.repair_information = true;
  std::istringstream in(text);
  const G2oReadResult r = readG2o(in, &repaired, options);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.num_edges, 3);
  EXPECT_EQ(r.num_repaired_information, 2);
  ASSERT_EQ(r.repairs.size(), 2u);
  EXPECT_EQ(r.repairs[0].line, 5);
  EXPECT_EQ(r.repairs[1].line, 6);
  EXPECT_NEAR(r.repairs[0].min_eigenvalue, -50.0, 1e-9);
  // Nearest PSD: the -50 eigenvalue (eigenvector (1, -1)/sqrt(2)) becomes 0, so the Frobenius
  // change is 50 and the x-y block becomes [[125, 125], [125, 125]].
  EXPECT_NEAR(r.repairs[0].frobenius_change, 50.0, 1e-9);
  // The well-formed edge is not touched and the repaired ones are exactly what was stated.
  int checked = 0;
  for (const auto& [id, edge] : repaired.edges()) {
    const Eigen::MatrixXd& info = edge.information;
    ASSERT_EQ(info.rows(), 6);
    if (edge.vertices[0] == 0 && edge.vertices[1] == 1) {
      EXPECT_EQ(info(0, 1), 0.0);
      EXPECT_EQ(info(0, 0), 100.0);
    } else {
      EXPECT_NEAR(info(0, 0), 125.0, 1e-9);
      EXPECT_NEAR(info(0, 1), 125.0, 1e-9);
      EXPECT_NEAR(info(1, 1), 125.0, 1e-9);
      EXPECT_NEAR(info(2, 2), 100.0, 1e-9);
      EXPECT_NEAR(info(5, 5), 400.0, 1e-9);
      EXPECT_EQ((info - info.transpose()).norm(), 0.0);
      EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(info).eigenvalues().minCoeff(),
                -1e-9);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 3);

  // A positive semi-definite matrix is left alone, and so is a file without indefinite ones.
  Eigen::MatrixXd out;
  double min_eigenvalue = 1.0;
  EXPECT_FALSE(nearestPositiveSemiDefinite(Eigen::Matrix3d::Identity(), &out, &min_eigenvalue));
  EXPECT_DOUBLE_EQ(min_eigenvalue, 1.0);
  Eigen::Matrix2d singular;
  singular << 1, 1, 1, 1;
  EXPECT_FALSE(nearestPositiveSemiDefinite(singular, &out));
  PoseGraph plain;
  std::istringstream plain_in(
      "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
      "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n");
  const G2oReadResult untouched = readG2o(plain_in, &plain, options);
  ASSERT_TRUE(untouched.ok);
  EXPECT_EQ(untouched.num_repaired_information, 0);
}

}  // namespace
}  // namespace osm_graph_slam
