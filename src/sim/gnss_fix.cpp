#include "osm_graph_slam/sim/gnss_fix.h"

#include <Eigen/Dense>
#include <cmath>

namespace osm_graph_slam::sim {
namespace {

using Matrix4 = Eigen::Matrix4d;
using Vector4 = Eigen::Vector4d;

/// Rows [-line of sight, 1]: the derivative of each range by (position, clock).
Eigen::MatrixXd geometryMatrix(const std::vector<Pseudorange>& ranges, const Vector4& state) {
  Eigen::MatrixXd h(ranges.size(), 4);
  for (size_t i = 0; i < ranges.size(); ++i) {
    const Eigen::Vector3d line_of_sight = (ranges[i].satellite - state.head<3>()).normalized();
    h.row(Eigen::Index(i)) << -line_of_sight.transpose(), 1.0;
  }
  return h;
}

Eigen::VectorXd rangeResiduals(const std::vector<Pseudorange>& ranges, const Vector4& state) {
  Eigen::VectorXd r(ranges.size());
  for (size_t i = 0; i < ranges.size(); ++i) {
    const double predicted = (ranges[i].satellite - state.head<3>()).norm() + state(3);
    r(Eigen::Index(i)) = ranges[i].range_m - predicted;
  }
  return r;
}

/// A geometry the receiver cannot solve: (H^T H) not positive definite to working precision.
bool singular(const Matrix4& normal) {
  const Eigen::SelfAdjointEigenSolver<Matrix4> eig(normal);
  return eig.eigenvalues()(0) <= 1e-9 * std::max(1.0, eig.eigenvalues()(3));
}

}  // namespace

PositionFix solvePositionFix(const std::vector<Pseudorange>& ranges,
                             const Eigen::Vector3d& initial_position, int max_iterations) {
  PositionFix fix;
  if (ranges.size() < 4) return fix;
  Vector4 state;
  state << initial_position, 0.0;
  Matrix4 normal = Matrix4::Zero();
  for (int it = 0; it < max_iterations; ++it) {
    const Eigen::MatrixXd h = geometryMatrix(ranges, state);
    normal = h.transpose() * h;
    if (singular(normal)) return fix;
    const Vector4 step = normal.ldlt().solve(h.transpose() * rangeResiduals(ranges, state));
    state += step;
    fix.iterations = it + 1;
    if (step.head<3>().norm() < 1e-7 && std::abs(step(3)) < 1e-7) break;
  }
  const Eigen::MatrixXd h = geometryMatrix(ranges, state);
  normal = h.transpose() * h;
  if (singular(normal)) return fix;
  const Matrix4 cofactor = normal.inverse();  // (H^T H)^-1: covariance per unit range variance
  fix.valid = true;
  fix.position = state.head<3>();
  fix.clock_bias_m = state(3);
  fix.hdop = std::sqrt(cofactor(0, 0) + cofactor(1, 1));
  fix.vdop = std::sqrt(cofactor(2, 2));
  return fix;
}

}  // namespace osm_graph_slam::sim
