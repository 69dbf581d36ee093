// Baseline: the pose-graph formulation of the Ceres documentation examples, written from the docs.
#include "osm_graph_slam/eval/reference_formulation.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>
#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <chrono>
#include <cmath>
#include <map>

namespace osm_graph_slam {
namespace {

template <typename T>
T normalizeAngle(const T& angle) {
  const T two_pi(2.0 * M_PI);
  using std::floor;
  return angle - two_pi * floor((angle + T(M_PI)) / two_pi);
}

struct AnglePlus {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    *x_plus_delta = normalizeAngle(*x + *delta);
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    *y_minus_x = normalizeAngle(*y - *x);
    return true;
  }
};

// Residual of the 2D documentation example: [R(yaw_a)ᵀ(p_b − p_a) − p_ab; yaw_b − yaw_a − yaw_ab].
struct PoseGraph2dTerm {
  double x_ab, y_ab, yaw_ab;
  Eigen::Matrix3d sqrt_information;

  template <typename T>
  bool operator()(const T* x_a, const T* y_a, const T* yaw_a, const T* x_b, const T* y_b,
                  const T* yaw_b, T* residuals) const {
    using std::cos;
    using std::sin;
    const T c = cos(*yaw_a), s = sin(*yaw_a);
    const T dx = *x_b - *x_a, dy = *y_b - *y_a;
    Eigen::Matrix<T, 3, 1> r;
    r[0] = c * dx + s * dy - x_ab;
    r[1] = -s * dx + c * dy - y_ab;
    r[2] = normalizeAngle(*yaw_b - *yaw_a - T(yaw_ab));
    Eigen::Map<Eigen::Matrix<T, 3, 1>> out(residuals);
    out = sqrt_information.cast<T>() * r;
    return true;
  }
};

// Residual of the 3D documentation example: [p_ab_est − p_ab; 2·vec(q_ab · q_ab_est⁻¹)].
struct PoseGraph3dTerm {
  Eigen::Vector3d p_ab;
  Eigen::Quaterniond q_ab;
  Eigen::Matrix<double, 6, 6> sqrt_information;

  template <typename T>
  bool operator()(const T* p_a_ptr, const T* q_a_ptr, const T* p_b_ptr, const T* q_b_ptr,
                  T* residuals) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(p_a_ptr), p_b(p_b_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_ptr), q_b(q_b_ptr);
    const Eigen::Quaternion<T> q_a_inverse = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab_estimated = q_a_inverse * q_b;
    const Eigen::Matrix<T, 3, 1> p_ab_estimated = q_a_inverse * (p_b - p_a);
    const Eigen::Quaternion<T> delta_q = q_ab.template cast<T>() * q_ab_estimated.conjugate();
    Eigen::Matrix<T, 6, 1> r;
    r.template head<3>() = p_ab_estimated - p_ab.template cast<T>();
    r.template tail<3>() = T(2.0) * delta_q.vec();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(residuals);
    out = sqrt_information.template cast<T>() * r;
    return true;
  }
};

// S with SᵀS = Ω' where Ω' = M⁻ᵀ Ω M⁻¹ (see the header).
Eigen::MatrixXd sqrtOfMapped(const Eigen::MatrixXd& information, const Eigen::MatrixXd& m_inv) {
  const Eigen::MatrixXd mapped = m_inv.transpose() * information * m_inv;
  const Eigen::MatrixXd symmetric = 0.5 * (mapped + mapped.transpose());
  return Eigen::LLT<Eigen::MatrixXd>(symmetric).matrixU();
}

struct Pose2dBlocks {
  double x, y, yaw;
};
struct Pose3dBlocks {
  Eigen::Vector3d p;
  Eigen::Quaterniond q;
};

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace

ReferenceSolveResult solveReferenceFormulation(const PoseGraph& graph,
                                               const OptimizerOptions& options,
                                               PoseGraph* solution) {
  ReferenceSolveResult result;
  for (const auto& [id, e] : graph.edges()) {
    if (e.type != EdgeType::kSE2 && e.type != EdgeType::kSE3) {
      result.message = std::string("reference formulation has no ") + toString(e.type) + " edge";
      return result;
    }
  }
  const auto start = std::chrono::steady_clock::now();
  std::map<int, Pose2dBlocks> poses2d;
  std::map<int, Pose3dBlocks> poses3d;
  for (const auto& [id, v] : graph.vertices()) {
    if (v.type == VertexType::kSE2) poses2d[id] = {v.x[0], v.x[1], v.x[2]};
    if (v.type == VertexType::kSE3) {
      poses3d[id] = {Eigen::Vector3d(v.x[0], v.x[1], v.x[2]),
                     Eigen::Quaterniond(v.x[6], v.x[3], v.x[4], v.x[5])};
    }
  }

  ceres::Problem problem;
  ceres::Manifold* angle_manifold = new ceres::AutoDiffManifold<AnglePlus, 1, 1>;
  ceres::Manifold* quaternion_manifold = new ceres::EigenQuaternionManifold;
  bool angle_manifold_used = false, quaternion_manifold_used = false;
  for (const auto& [id, e] : graph.edges()) {
    const Eigen::VectorXd& z = e.measurement;
    if (e.type == EdgeType::kSE2) {
      const double c = std::cos(z[2]), s = std::sin(z[2]);
      Eigen::Matrix3d m_inv = Eigen::Matrix3d::Identity();  // M = diag(R_z, 1)
      m_inv.topLeftCorner<2, 2>() << c, s, -s, c;
      Pose2dBlocks& a = poses2d.at(e.vertices[0]);
      Pose2dBlocks& b = poses2d.at(e.vertices[1]);
      auto* cost = new ceres::AutoDiffCostFunction<PoseGraph2dTerm, 3, 1, 1, 1, 1, 1, 1>(
          new PoseGraph2dTerm{z[0], z[1], z[2], sqrtOfMapped(e.information, m_inv)});
      problem.AddResidualBlock(cost, nullptr, &a.x, &a.y, &a.yaw, &b.x, &b.y, &b.yaw);
      problem.SetManifold(&a.yaw, angle_manifold);
      problem.SetManifold(&b.yaw, angle_manifold);
      angle_manifold_used = true;
    } else {
      const Eigen::Quaterniond q_ab(z[6], z[3], z[4], z[5]);
      const Eigen::Matrix3d r_z = q_ab.toRotationMatrix();
      Eigen::Matrix<double, 6, 6> m_inv = Eigen::Matrix<double, 6, 6>::Zero();
      m_inv.topLeftCorner<3, 3>() = r_z.transpose();  // M = diag(R_z, −2 R_z)
      m_inv.bottomRightCorner<3, 3>() = -0.5 * r_z.transpose();
      Pose3dBlocks& a = poses3d.at(e.vertices[0]);
      Pose3dBlocks& b = poses3d.at(e.vertices[1]);
      auto* cost = new ceres::AutoDiffCostFunction<PoseGraph3dTerm, 6, 3, 4, 3, 4>(
          new PoseGraph3dTerm{z.head<3>(), q_ab, sqrtOfMapped(e.information, m_inv)});
      problem.AddResidualBlock(cost, nullptr, a.p.data(), a.q.coeffs().data(), b.p.data(),
                               b.q.coeffs().data());
      problem.SetManifold(a.q.coeffs().data(), quaternion_manifold);
      problem.SetManifold(b.q.coeffs().data(), quaternion_manifold);
      quaternion_manifold_used = true;
    }
  }
  // The problem owns the manifolds it was given; delete the ones it never saw.
  if (!angle_manifold_used) delete angle_manifold;
  if (!quaternion_manifold_used) delete quaternion_manifold;

  for (auto& [id, p] : poses2d) {
    if (!graph.isFixed(id) || !problem.HasParameterBlock(&p.x)) continue;
    problem.SetParameterBlockConstant(&p.x);
    problem.SetParameterBlockConstant(&p.y);
    problem.SetParameterBlockConstant(&p.yaw);
  }
  for (auto& [id, p] : poses3d) {
    if (!graph.isFixed(id) || !problem.HasParameterBlock(p.p.data())) continue;
    problem.SetParameterBlockConstant(p.p.data());
    problem.SetParameterBlockConstant(p.q.coeffs().data());
  }

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  const bool suite_sparse = options.sparse_library != SparseLibrary::kEigenSparse &&
                            ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE);
  solver.sparse_linear_algebra_library_type =
      suite_sparse ? ceres::SUITE_SPARSE : ceres::EIGEN_SPARSE;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.gradient_tolerance = options.gradient_tolerance;
  solver.parameter_tolerance = options.parameter_tolerance;
  solver.num_threads = std::max(1, options.num_threads);
  solver.initial_trust_region_radius = options.initial_trust_region_radius;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  result.time_ms = msSince(start);

  result.ok = summary.IsSolutionUsable();
  result.message = summary.message;
  result.termination = ceres::TerminationTypeToString(summary.termination_type);
  result.initial_chi2 = 2.0 * summary.initial_cost;  // Ceres cost is ½Σ|r|²
  result.final_chi2 = 2.0 * summary.final_cost;
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  if (options.verbose) result.report = summary.FullReport();

  if (solution != nullptr) {
    *solution = graph;
    for (const auto& [id, p] : poses2d) solution->setVertexSE2(id, Pose2(p.x, p.y, p.yaw));
    for (const auto& [id, p] : poses3d) {
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.linear() = p.q.normalized().toRotationMatrix();
      pose.translation() = p.p;
      solution->setVertexSE3(id, pose);
    }
  }
  return result;
}

}  // namespace osm_graph_slam
