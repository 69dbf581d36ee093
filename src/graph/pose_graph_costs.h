#pragma once
// Ceres side of the pose graph (private to src/graph and its unit tests): manifolds and cost
// functions. Kept out of include/ so only the few files that optimise pay for the Ceres headers.
#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>

#include <memory>

#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam::graph_detail {

/// SE3 stored as (t, q xyzw) with 6 tangent dimensions: t ⊞ δt = t + δt (world frame),
/// q ⊞ δθ = q ⊗ Exp(δθ) (body frame). PlusJacobian is the "lifting" [I6; 0]: every cost touching
/// an SE3 block reports d r / d δ in its first 6 Jacobian columns (and 0 in the 7th), so Ceres'
/// product J · PlusJacobian is exactly the tangent Jacobian without a 7×6 multiply per block.
class SE3LiftedManifold : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 7; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// SE2 (x, y, θ): additive with θ wrapped to (−π, π].
class SE2Manifold : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 3; }
  int TangentSize() const override { return 3; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// True derivative d(q ⊗ Exp(δθ))/dδθ at δθ = 0 of the 4 quaternion coefficients (xyzw), 4×3
/// row-major; used to turn automatic-differentiation Jacobians into lifted tangent Jacobians.
void quaternionRightPlusJacobian(const double* q_xyzw, double* jacobian_4x3);

/// The residual r = S·e of an edge (S = sqrt information). For SE3 blocks the Jacobian follows
/// the SE3LiftedManifold convention. analytic=false uses automatic differentiation for the SE2
/// and SE3 relative edges (the other types are always automatic).
std::unique_ptr<ceres::CostFunction> makeCostFunction(const PoseGraph::Edge& edge, bool analytic);

/// Ceres loss for a g2o-style kernel (nullptr for none). Ceres minimises ½Σρ, g2o Σρ: same
/// minimiser.
std::unique_ptr<ceres::LossFunction> makeLossFunction(const RobustKernel& kernel);

}  // namespace osm_graph_slam::graph_detail
