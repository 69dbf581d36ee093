// The closed-form and lifted automatic Jacobians of every edge type equal central finite
// differences of the residual through the manifold's Plus (d r(x ⊞ δ) / dδ at δ = 0).
#include <gtest/gtest.h>

#include <random>

#include "../../src/graph/pose_graph_costs.h"
#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam {
namespace {

using graph_detail::makeCostFunction;
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Block {
  VertexType type;
  std::vector<double> x;
};

int tangentSize(VertexType t) {
  if (t == VertexType::kSE3) return 6;
  if (t == VertexType::kScale) return 1;
  return t == VertexType::kSE2 || t == VertexType::kPointXYZ ? 3 : 2;
}

std::vector<double> plus(const Block& b, const Eigen::VectorXd& delta) {
  std::vector<double> out(b.x.size());
  if (b.type == VertexType::kSE3) {
    graph_detail::SE3LiftedManifold().Plus(b.x.data(), delta.data(), out.data());
  } else if (b.type == VertexType::kSE2) {
    graph_detail::SE2Manifold().Plus(b.x.data(), delta.data(), out.data());
  } else {
    for (size_t k = 0; k < out.size(); ++k) out[k] = b.x[k] + delta[k];
  }
  return out;
}

Eigen::VectorXd residual(const ceres::CostFunction& cost,
                         const std::vector<std::vector<double>>& x) {
  std::vector<const double*> ptrs;
  for (const auto& v : x) ptrs.push_back(v.data());
  Eigen::VectorXd r(cost.num_residuals());
  EXPECT_TRUE(cost.Evaluate(ptrs.data(), r.data(), nullptr));
  return r;
}

// Max |J_reported · PlusJacobian − J_numeric| over all blocks, relative to max |J_numeric|.
double jacobianError(const PoseGraph::Edge& edge, const std::vector<Block>& blocks, bool analytic) {
  const std::unique_ptr<ceres::CostFunction> cost = makeCostFunction(edge, analytic);
  const int m = cost->num_residuals();
  std::vector<std::vector<double>> x;
  for (const Block& b : blocks) x.push_back(b.x);
  std::vector<const double*> ptrs;
  for (const auto& v : x) ptrs.push_back(v.data());
  std::vector<RowMajor> jac;
  std::vector<double*> jac_ptrs;
  for (const Block& b : blocks) jac.emplace_back(m, static_cast<int>(b.x.size()));
  for (auto& j : jac) jac_ptrs.push_back(j.data());
  Eigen::VectorXd r(m);
  EXPECT_TRUE(cost->Evaluate(ptrs.data(), r.data(), jac_ptrs.data()));

  double worst = 0.0, scale = 1e-12;
  for (size_t i = 0; i < blocks.size(); ++i) {
    const int n = tangentSize(blocks[i].type);
    RowMajor reported = jac[i].leftCols(n);  // lifted: first n columns are d r / d δ
    if (blocks[i].type == VertexType::kSE3) {
      EXPECT_EQ(jac[i].col(6).norm(), 0.0);
    }
    const double h = 1e-6;
    for (int k = 0; k < n; ++k) {
      Eigen::VectorXd d = Eigen::VectorXd::Zero(n);
      d[k] = h;
      auto xp = x, xm = x;
      xp[i] = plus(blocks[i], d);
      xm[i] = plus(blocks[i], -d);
      const Eigen::VectorXd numeric = (residual(*cost, xp) - residual(*cost, xm)) / (2 * h);
      worst = std::max(worst, (reported.col(k) - numeric).cwiseAbs().maxCoeff());
      scale = std::max(scale, numeric.cwiseAbs().maxCoeff());
    }
  }
  return worst / scale;
}

std::vector<double> randomSE3(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return {3 * n(rng), 3 * n(rng), n(rng), q.x(), q.y(), q.z(), q.w()};
}

std::vector<double> randomSE2(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return {3 * n(rng), 3 * n(rng), wrapAngle(2 * n(rng))};
}

PoseGraph::Edge makeEdge(EdgeType type, Eigen::VectorXd measurement, std::mt19937& rng) {
  const int d = errorDimension(type);
  Eigen::MatrixXd a = Eigen::MatrixXd::Random(d, d);
  PoseGraph::Edge e;
  e.type = type;
  e.measurement = std::move(measurement);
  e.information = a * a.transpose() + Eigen::MatrixXd::Identity(d, d);
  e.sqrt_information = Eigen::LLT<Eigen::MatrixXd>(e.information).matrixU();
  return e;
}

Eigen::VectorXd vec(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), v.size());
}

TEST(PoseGraphJacobians, EveryEdgeTypeMatchesFiniteDifferences) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 20; ++trial) {
    const Block se3a{VertexType::kSE3, randomSE3(rng)};
    const Block se3b{VertexType::kSE3, randomSE3(rng)};
    const Block se2a{VertexType::kSE2, randomSE2(rng)};
    const Block se2b{VertexType::kSE2, randomSE2(rng)};
    const Block xy{VertexType::kPointXY, {4.0, -2.0}};
    const Block xyz{VertexType::kPointXYZ, {4.0, -2.0, 1.0}};
    const Block scale{VertexType::kScale, {1.03}};
    const Eigen::VectorXd z7 = vec(randomSE3(rng)), z3 = vec(randomSE2(rng));
    const Eigen::Vector2d z2(1.0, 0.5);
    Eigen::VectorXd planes(8);
    planes << Eigen::Vector3d(0.05, -0.02, 1.0).normalized(), -0.9,
        Eigen::Vector3d(-0.01, 0.03, 1.0).normalized(), -0.95;
    struct Case {
      EdgeType type;
      Eigen::VectorXd z;
      std::vector<Block> blocks;
    };
    const std::vector<Case> cases = {
        {EdgeType::kSE3, z7, {se3a, se3b}},
        {EdgeType::kSE2, z3, {se2a, se2b}},
        {EdgeType::kSE3SE2, z3, {se3a, se2b}},
        {EdgeType::kPriorSE3, z7, {se3a}},
        {EdgeType::kPriorSE3XY, z2, {se3a}},
        {EdgeType::kPriorSE3XYZ, Eigen::Vector3d(1, 2, 3), {se3a}},
        {EdgeType::kPriorSE3Yaw, Eigen::VectorXd::Constant(1, 0.3), {se3a}},
        {EdgeType::kSE3YawDifference, Eigen::VectorXd::Constant(1, 0.3), {se3a, se3b}},
        {EdgeType::kPriorSE2, z3, {se2a}},
        {EdgeType::kSE2PointXY, z2, {se2a, xy}},
        {EdgeType::kSE3PointXY, z2, {se3a, xy}},
        {EdgeType::kSE3PlanePair, planes, {se3a, se3b}},
        {EdgeType::kPriorPointXYZ, Eigen::Vector3d(1, 2, 3), {xyz}},
        {EdgeType::kPointXYZGaussMarkov,
         Eigen::VectorXd::Constant(1, 0.7),
         {xyz, Block{VertexType::kPointXYZ, {-1.0, 3.0, 0.5}}}},
        {EdgeType::kSE3PositionWithOffset, Eigen::Vector3d(1, 2, 3), {se3a, xyz}},
        {EdgeType::kSE3Scaled, z7, {se3a, se3b, scale}},
        {EdgeType::kPriorScale, Eigen::VectorXd::Constant(1, 1.0), {scale}},
        {EdgeType::kScaleDifference,
         Eigen::VectorXd::Constant(1, 0.01),
         {scale, Block{VertexType::kScale, {0.98}}}},
    };
    for (const Case& c : cases) {
      const PoseGraph::Edge edge = makeEdge(c.type, c.z, rng);
      for (bool analytic : {true, false}) {
        EXPECT_LT(jacobianError(edge, c.blocks, analytic), 1e-6)
            << toString(c.type) << " analytic=" << analytic << " trial " << trial;
      }
    }
  }
}

TEST(PoseGraphJacobians, AnalyticAndAutomaticResidualsAgree) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    for (EdgeType type : {EdgeType::kSE3, EdgeType::kSE2}) {
      const bool is3d = type == EdgeType::kSE3;
      const VertexType vt = is3d ? VertexType::kSE3 : VertexType::kSE2;
      const std::vector<std::vector<double>> x = {is3d ? randomSE3(rng) : randomSE2(rng),
                                                  is3d ? randomSE3(rng) : randomSE2(rng)};
      const PoseGraph::Edge e = makeEdge(type, vec(is3d ? randomSE3(rng) : randomSE2(rng)), rng);
      const Eigen::VectorXd ra = residual(*makeCostFunction(e, true), x);
      const Eigen::VectorXd rb = residual(*makeCostFunction(e, false), x);
      EXPECT_LT((ra - rb).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, ra.norm()))
          << toString(type) << " " << toString(vt);
    }
  }
}

}  // namespace
}  // namespace osm_graph_slam
