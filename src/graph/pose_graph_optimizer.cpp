// PoseGraph::optimize / chi2 / marginalCovariance: builds a Ceres problem from the active edges.
#include <ceres/covariance.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <chrono>
#include <set>

#include "osm_graph_slam/graph/pose_graph.h"
#include "pose_graph_costs.h"

namespace osm_graph_slam {
namespace {

using graph_detail::makeCostFunction;
using graph_detail::makeLossFunction;

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

const ceres::Manifold* manifoldFor(VertexType type) {
  static const graph_detail::SE3LiftedManifold se3;
  static const graph_detail::SE2Manifold se2;
  if (type == VertexType::kSE3) return &se3;
  if (type == VertexType::kSE2) return &se2;
  return nullptr;
}

// One active edge: its cost (owned by the problem) and its parameter blocks.
struct ActiveResidual {
  const ceres::CostFunction* cost = nullptr;
  std::array<double*, kMaxEdgeVertices> blocks{{nullptr, nullptr, nullptr}};
};

// A Ceres problem over the edges of level ≤ level of a graph whose vertex storage it points into.
struct GraphProblem {
  std::unique_ptr<ceres::Problem> problem;
  std::vector<ActiveResidual> residuals;
  std::set<int> vertex_ids;
  int num_fixed = 0;
};

bool allFixed(const PoseGraph::Edge& edge, const std::map<int, PoseGraph::Vertex>& vertices) {
  for (int k = 0; k < edge.num_vertices; ++k)
    if (!vertices.at(edge.vertices[k]).fixed) return false;
  return true;
}

GraphProblem buildProblem(const std::map<int, PoseGraph::Edge>& edges,
                          std::map<int, PoseGraph::Vertex>& vertices, int level, bool analytic,
                          bool skip_constant = false) {
  GraphProblem gp;
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;  // shared static manifolds
  options.disable_all_safety_checks = true;  // blocks and sizes are validated by PoseGraph
  gp.problem = std::make_unique<ceres::Problem>(options);
  for (const auto& [id, edge] : edges) {
    if (edge.level > level) continue;
    if (skip_constant && allFixed(edge, vertices)) continue;
    ActiveResidual r;
    for (int k = 0; k < edge.num_vertices; ++k) {
      r.blocks[k] = vertices.at(edge.vertices[k]).x.data();
      gp.vertex_ids.insert(edge.vertices[k]);
    }
    std::unique_ptr<ceres::CostFunction> cost = makeCostFunction(edge, analytic);
    r.cost = cost.get();
    gp.problem->AddResidualBlock(cost.release(), makeLossFunction(edge.kernel).release(),
                                 r.blocks.data(), edge.num_vertices);
    gp.residuals.push_back(r);
  }
  for (int id : gp.vertex_ids) {
    PoseGraph::Vertex& v = vertices.at(id);
    if (const ceres::Manifold* m = manifoldFor(v.type)) {
      gp.problem->SetManifold(v.x.data(), const_cast<ceres::Manifold*>(m));
    }
    if (v.fixed) {
      gp.problem->SetParameterBlockConstant(v.x.data());
      ++gp.num_fixed;
    }
  }
  return gp;
}

// Σ eᵀΩe without robust kernels (the residuals are S e, so each term is |r|²).
double chi2Of(const std::vector<ActiveResidual>& residuals) {
  double sum = 0.0;
  double r[6];
  for (const ActiveResidual& a : residuals) {
    if (!a.cost->Evaluate(a.blocks.data(), r, nullptr)) continue;
    for (int k = 0; k < a.cost->num_residuals(); ++k) sum += r[k] * r[k];
  }
  return sum;
}

ceres::SparseLinearAlgebraLibraryType suiteSparseIfAvailable() {
  return ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)
             ? ceres::SUITE_SPARSE
             : ceres::EIGEN_SPARSE;
}

ceres::SparseLinearAlgebraLibraryType sparseLibrary(const OptimizerOptions& options,
                                                    int free_vertices) {
  const bool eigen = options.sparse_library == SparseLibrary::kEigenSparse ||
                     (options.sparse_library == SparseLibrary::kAuto &&
                      free_vertices <= options.auto_eigen_max_free_vertices);
  return eigen ? ceres::EIGEN_SPARSE : suiteSparseIfAvailable();
}

}  // namespace

double PoseGraph::chi2(int level) const {
  // The problem points into vertex storage; chi² only evaluates, so a copy keeps this const.
  std::map<int, Vertex> vertices = vertices_;
  const GraphProblem gp = buildProblem(edges_, vertices, level, true);
  return chi2Of(gp.residuals);
}

OptimizationResult PoseGraph::optimize(int level, const OptimizerOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  OptimizationResult result;
  GraphProblem gp = buildProblem(edges_, vertices_, level, options.analytic_jacobians,
                                 options.skip_constant_edges);
  result.num_edges = static_cast<int>(gp.residuals.size());
  result.num_vertices = static_cast<int>(gp.vertex_ids.size());
  result.num_fixed_vertices = gp.num_fixed;
  result.initial_chi2 = chi2Of(gp.residuals);
  result.final_chi2 = result.initial_chi2;
  if (gp.residuals.empty() || gp.num_fixed == result.num_vertices) {
    result.success = true;
    result.termination = TerminationReason::kNothingToSolve;
    result.message = gp.residuals.empty() ? "no edge with level <= " + std::to_string(level)
                                          : "every active vertex is fixed";
    result.time_ms = msSince(start);
    return result;
  }

  // Fixed blocks are constant in Ceres; the snapshot makes "bit for bit" a guarantee anyway.
  std::vector<std::pair<double*, std::array<double, 7>>> fixed_snapshot;
  for (int id : gp.vertex_ids) {
    Vertex& v = vertices_.at(id);
    if (v.fixed) fixed_snapshot.emplace_back(v.x.data(), v.x);
  }

  ceres::Solver::Options solver;
  solver.minimizer_type = ceres::TRUST_REGION;
  solver.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.sparse_linear_algebra_library_type =
      sparseLibrary(options, result.num_vertices - result.num_fixed_vertices);
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.gradient_tolerance = options.gradient_tolerance;
  solver.parameter_tolerance = options.parameter_tolerance;
  solver.num_threads = std::max(1, options.num_threads);
  solver.initial_trust_region_radius = options.initial_trust_region_radius;
  solver.logging_type = ceres::SILENT;

  ceres::Solver::Summary summary;
  const auto solve_start = std::chrono::steady_clock::now();
  ceres::Solve(solver, gp.problem.get(), &summary);
  result.solve_ms = msSince(solve_start);

  for (auto& [ptr, values] : fixed_snapshot) std::copy(values.begin(), values.end(), ptr);

  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  result.message = summary.message;
  result.linear_solver =
      std::string(ceres::LinearSolverTypeToString(summary.linear_solver_type_used)) + "/" +
      ceres::SparseLinearAlgebraLibraryTypeToString(summary.sparse_linear_algebra_library_type);
  switch (summary.termination_type) {
    case ceres::CONVERGENCE:
      result.termination = TerminationReason::kConverged;
      result.success = true;
      break;
    case ceres::NO_CONVERGENCE:
      result.termination = TerminationReason::kMaxIterations;
      result.success = true;
      break;
    default:
      result.termination = TerminationReason::kFailure;
      result.success = false;
      break;
  }
  result.final_chi2 = chi2Of(gp.residuals);
  if (options.verbose) result.report = summary.FullReport();
  result.time_ms = msSince(start);
  return result;
}

bool PoseGraph::marginalCovariance(int vertex_id, Eigen::MatrixXd* covariance, int level) {
  std::map<int, Eigen::MatrixXd> out;
  if (!marginalCovariances({vertex_id}, &out, level)) return false;
  *covariance = out.at(vertex_id);
  return true;
}

bool PoseGraph::marginalCovariances(const std::vector<int>& vertex_ids,
                                    std::map<int, Eigen::MatrixXd>* covariances, int level) {
  for (int id : vertex_ids)
    if (!vertices_.count(id)) {
      fail("covariance: unknown vertex " + std::to_string(id));
      return false;
    }
  GraphProblem gp = buildProblem(edges_, vertices_, level, true);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (int id : vertex_ids) {
    if (!gp.vertex_ids.count(id)) {
      fail("covariance: vertex " + std::to_string(id) +
           " has no edge of level <= " + std::to_string(level));
      return false;
    }
    double* block = vertices_.at(id).x.data();
    const int dim = gp.problem->ParameterBlockTangentSize(block);
    (*covariances)[id] = Eigen::MatrixXd::Zero(dim, dim);  // a fixed vertex has no uncertainty
    if (!vertices_.at(id).fixed) blocks.emplace_back(block, block);
  }
  if (blocks.empty()) return true;
  // One factorisation for every block asked for.
  ceres::Covariance::Options options;
  options.sparse_linear_algebra_library_type = suiteSparseIfAvailable();
  options.algorithm_type = ceres::SPARSE_QR;
  ceres::Covariance cov(options);
  if (!cov.Compute(blocks, gp.problem.get())) {
    fail("covariance: Jacobian is rank deficient (fix a vertex or add a prior to set the gauge)");
    return false;
  }
  for (int id : vertex_ids) {
    if (vertices_.at(id).fixed) continue;
    double* block = vertices_.at(id).x.data();
    const int dim = static_cast<int>((*covariances)[id].rows());
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(dim, dim);
    if (!cov.GetCovarianceBlockInTangentSpace(block, block, c.data())) {
      fail("covariance: Ceres could not return the block of vertex " + std::to_string(id));
      return false;
    }
    (*covariances)[id] = c;
  }
  return true;
}

}  // namespace osm_graph_slam
