#include "pose_graph_costs.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/sized_cost_function.h>

#include <cmath>

namespace osm_graph_slam::graph_detail {
namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

Matrix3d skew(const Vector3d& v) {
  Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Quaterniond expRotation(const double* d) {
  const Vector3d delta(d[0], d[1], d[2]);
  const double angle = delta.norm();
  if (angle < 1e-12) return Quaterniond(1.0, 0.5 * d[0], 0.5 * d[1], 0.5 * d[2]).normalized();
  const Vector3d axis = delta / angle;
  return Quaterniond(Eigen::AngleAxisd(angle, axis));
}

Vector3d logRotation(Quaterniond q) {
  if (q.w() < 0.0) q.coeffs() *= -1.0;
  const double vnorm = q.vec().norm();
  if (vnorm < 1e-12) return 2.0 * q.vec();
  return (2.0 * std::atan2(vnorm, q.w()) / vnorm) * q.vec();
}

// Angle wrapped to [−π, π) in a form automatic differentiation understands.
template <typename T>
T normalizeAngle(const T& a) {
  const T two_pi(2.0 * M_PI);
  using std::floor;
  return a - two_pi * floor((a + T(M_PI)) / two_pi);
}

// (x, y, yaw) of an SE3 parameter block (t, q xyzw).
template <typename T>
void planarFromSE3(const T* x, T* p) {
  using std::atan2;
  const T &qx = x[3], &qy = x[4], &qz = x[5], &qw = x[6];
  p[0] = x[0];
  p[1] = x[1];
  p[2] = atan2(T(2.0) * (qw * qz + qx * qy), T(1.0) - T(2.0) * (qy * qy + qz * qz));
}

// g2o SE2 error of toVector(Z⁻¹ · (Xi⁻¹ Xj)), Xi = (x, y, θ).
template <typename T>
void se2RelativeError(const T* xi, const T* xj, const double* z, T* e) {
  using std::cos;
  using std::sin;
  const T ci = cos(xi[2]), si = sin(xi[2]);
  const T dx = xj[0] - xi[0], dy = xj[1] - xi[1];
  const T ex = ci * dx + si * dy - z[0];
  const T ey = -si * dx + ci * dy - z[1];
  const double cz = std::cos(z[2]), sz = std::sin(z[2]);
  e[0] = cz * ex + sz * ey;
  e[1] = -sz * ex + cz * ey;
  e[2] = normalizeAngle(xj[2] - xi[2] - T(z[2]));
}

// g2o SE3 error (t, q.vec with qw ≥ 0) of Z⁻¹ · (Xi⁻¹ Xj); xi == nullptr means identity. tz is
// Z's translation (times a scale, when one is estimated).
template <typename T>
void se3RelativeError(const T* xi, const T* xj, const Quaterniond& qz_inv,
                      const Eigen::Matrix<T, 3, 1>& tz, T* e) {
  using Vec3 = Eigen::Matrix<T, 3, 1>;
  using Quat = Eigen::Quaternion<T>;
  const Eigen::Map<const Vec3> tj(xj);
  const Eigen::Map<const Quat> qj(xj + 3);
  Vec3 tij = tj;
  Quat qij = qj;
  if (xi != nullptr) {
    const Eigen::Map<const Vec3> ti(xi);
    const Quat qi_inv = Eigen::Map<const Quat>(xi + 3).conjugate();
    tij = qi_inv * (tj - ti);
    qij = qi_inv * qj;
  }
  const Quat qz_inv_t = qz_inv.cast<T>();
  const Vec3 te = qz_inv_t * (tij - tz);
  const Quat qe = qz_inv_t * qij;
  const T sign = qe.w() < T(0.0) ? T(-1.0) : T(1.0);
  for (int k = 0; k < 3; ++k) {
    e[k] = te[k];
    e[3 + k] = sign * qe.vec()[k];
  }
}

template <int N, typename T>
void weigh(const Eigen::Matrix<double, N, N>& sqrt_info, const T* e, T* residuals) {
  const Eigen::Map<const Eigen::Matrix<T, N, 1>> err(e);
  Eigen::Map<Eigen::Matrix<T, N, 1>> out(residuals);
  out = sqrt_info.template cast<T>() * err;
}

// ---- automatic-differentiation functors (templated on the scalar) ------------------------------

struct SE2RelativeFunctor {
  Eigen::Vector3d z;
  Eigen::Matrix3d sqrt_info;
  template <typename T>
  bool operator()(const T* xi, const T* xj, T* r) const {
    T e[3];
    se2RelativeError(xi, xj, z.data(), e);
    weigh<3>(sqrt_info, e, r);
    return true;
  }
};

struct SE3RelativeFunctor {
  Quaterniond qz_inv;
  Vector3d tz;
  Eigen::Matrix<double, 6, 6> sqrt_info;
  template <typename T>
  bool operator()(const T* xi, const T* xj, T* r) const {
    T e[6];
    se3RelativeError<T>(xi, xj, qz_inv, tz.cast<T>(), e);
    weigh<6>(sqrt_info, e, r);
    return true;
  }
};

struct SE3ScaledFunctor {
  Quaterniond qz_inv;
  Vector3d tz;
  Eigen::Matrix<double, 6, 6> sqrt_info;
  template <typename T>
  bool operator()(const T* xi, const T* xj, const T* scale, T* r) const {
    T e[6];
    // Only the horizontal part in the from-frame: a vertical odometry drift (e.g. a LiDAR's
    // elevation bias on walls) is not a scale, and the floors that correct it must not pull one.
    const Eigen::Matrix<T, 3, 1> t(scale[0] * T(tz.x()), scale[0] * T(tz.y()), T(tz.z()));
    se3RelativeError<T>(xi, xj, qz_inv, t, e);
    weigh<6>(sqrt_info, e, r);
    return true;
  }
};

// e = x_to − x_from − z of one-value vertices (a random walk).
struct ScalarDifferenceFunctor {
  double z = 0.0;
  double sqrt_info = 1.0;
  template <typename T>
  bool operator()(const T* from, const T* to, T* r) const {
    r[0] = sqrt_info * (to[0] - from[0] - T(z));
    return true;
  }
};

struct PriorSE3Functor {
  Quaterniond qz_inv;
  Vector3d tz;
  Eigen::Matrix<double, 6, 6> sqrt_info;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    T e[6];
    se3RelativeError<T>(nullptr, x, qz_inv, tz.cast<T>(), e);
    weigh<6>(sqrt_info, e, r);
    return true;
  }
};

// Translation error rotated from the measurement's axes into the estimated building's (R(−e_θ)).
// A building matched through one facade is informed across that wall only; in the measurement's
// axes each edge's free direction would follow its own measured heading, and edges whose headings
// differ by a few degrees would meet far along the wall and drag the building there.
template <typename T>
void inEstimatedAxes(T* e) {
  using std::cos;
  using std::sin;
  const T c = cos(e[2]), s = sin(e[2]);
  const T x = c * e[0] + s * e[1];
  const T y = -s * e[0] + c * e[1];
  e[0] = x;
  e[1] = y;
}

struct SE3SE2Functor {
  Eigen::Vector3d z;
  Eigen::Matrix3d sqrt_info;
  template <typename T>
  bool operator()(const T* robot, const T* building, T* r) const {
    T planar[3], e[3];
    planarFromSE3(robot, planar);
    se2RelativeError(planar, building, z.data(), e);
    inEstimatedAxes(e);
    weigh<3>(sqrt_info, e, r);
    return true;
  }
};

template <int N>
struct PriorPositionFunctor {
  Eigen::Matrix<double, N, 1> z;
  Eigen::Matrix<double, N, N> sqrt_info;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    T e[N];
    for (int k = 0; k < N; ++k) e[k] = x[k] - z[k];
    weigh<N>(sqrt_info, e, r);
    return true;
  }
};

struct GaussMarkovFunctor {
  double phi = 1.0;
  Eigen::Matrix3d sqrt_info;
  template <typename T>
  bool operator()(const T* b1, const T* b2, T* r) const {
    T e[3];
    for (int k = 0; k < 3; ++k) e[k] = b2[k] - phi * b1[k];
    weigh<3>(sqrt_info, e, r);
    return true;
  }
};

struct PositionWithOffsetFunctor {
  Eigen::Vector3d z;
  Eigen::Matrix3d sqrt_info;
  template <typename T>
  bool operator()(const T* x, const T* b, T* r) const {
    T e[3];
    for (int k = 0; k < 3; ++k) e[k] = x[k] + b[k] - z[k];
    weigh<3>(sqrt_info, e, r);
    return true;
  }
};

struct PriorYawFunctor {
  double z = 0.0;
  double sqrt_info = 1.0;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    T planar[3];
    planarFromSE3(x, planar);
    r[0] = sqrt_info * normalizeAngle(planar[2] - T(z));
    return true;
  }
};

struct YawDifferenceFunctor {
  double z = 0.0;
  double sqrt_info = 1.0;
  template <typename T>
  bool operator()(const T* xi, const T* xj, T* r) const {
    T pi[3], pj[3];
    planarFromSE3(xi, pi);
    planarFromSE3(xj, pj);
    r[0] = sqrt_info * normalizeAngle(pj[2] - pi[2] - T(z));
    return true;
  }
};

struct PriorSE2Functor {
  Eigen::Vector3d z;
  Eigen::Matrix3d sqrt_info;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    const T origin[3] = {T(0.0), T(0.0), T(0.0)};
    T e[3];
    se2RelativeError(origin, x, z.data(), e);
    weigh<3>(sqrt_info, e, r);
    return true;
  }
};

// e = Xi⁻¹ p − z for a planar pose (x, y, θ).
template <typename T>
void pointError(const T* pose, const T* p, const Eigen::Vector2d& z, T* e) {
  using std::cos;
  using std::sin;
  const T c = cos(pose[2]), s = sin(pose[2]);
  const T dx = p[0] - pose[0], dy = p[1] - pose[1];
  e[0] = c * dx + s * dy - z[0];
  e[1] = -s * dx + c * dy - z[1];
}

struct SE2PointFunctor {
  Eigen::Vector2d z;
  Eigen::Matrix2d sqrt_info;
  template <typename T>
  bool operator()(const T* pose, const T* p, T* r) const {
    T e[2];
    pointError(pose, p, z, e);
    weigh<2>(sqrt_info, e, r);
    return true;
  }
};

// r = s·(n·x − c), x = Xline⁻¹ · Xpoint · p.
struct SE2PointOnLineFunctor {
  Eigen::Vector2d p, n;
  double c;
  double sqrt_info;
  template <typename T>
  bool operator()(const T* point_owner, const T* line_owner, T* r) const {
    using std::cos;
    using std::sin;
    const T wx = point_owner[0] + cos(point_owner[2]) * p.x() - sin(point_owner[2]) * p.y();
    const T wy = point_owner[1] + sin(point_owner[2]) * p.x() + cos(point_owner[2]) * p.y();
    const T dx = wx - line_owner[0], dy = wy - line_owner[1];
    const T cl = cos(line_owner[2]), sl = sin(line_owner[2]);
    const T lx = cl * dx + sl * dy, ly = -sl * dx + cl * dy;
    r[0] = T(sqrt_info) * (n.x() * lx + n.y() * ly - T(c));
    return true;
  }
};

struct SE3PointFunctor {
  Eigen::Vector2d z;
  Eigen::Matrix2d sqrt_info;
  template <typename T>
  bool operator()(const T* pose, const T* p, T* r) const {
    T planar[3], e[2];
    planarFromSE3(pose, planar);
    pointError(planar, p, z, e);
    weigh<2>(sqrt_info, e, r);
    return true;
  }
};

// Plane measured in the first SE3 frame, carried into the second, against the plane measured
// there: (n̂ₓ − nₓ, n̂ᵧ − nᵧ, d̂ − d). Floors are near level in base_link, so x and y of the unit
// normals are its two free directions.
struct SE3PlanePairFunctor {
  Eigen::Vector4d first, second;
  Eigen::Matrix3d sqrt_info;
  template <typename T>
  bool operator()(const T* xi, const T* xj, T* r) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> qi(xi + 3), qj(xj + 3);
    const Vec3 n_world = qi * first.head<3>().cast<T>();
    const Vec3 n_pred = qj.conjugate() * n_world;
    const Vec3 dt(xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]);
    T e[3] = {n_pred.x() - T(second.x()), n_pred.y() - T(second.y()),
              T(first[3]) + n_world.dot(dt) - T(second[3])};
    weigh<3>(sqrt_info, e, r);
    return true;
  }
};

// Converts ambient (7-column) SE3 Jacobians of an automatically differentiated cost into the
// lifted tangent form expected by SE3LiftedManifold.
class LiftedCost : public ceres::CostFunction {
 public:
  LiftedCost(std::unique_ptr<ceres::CostFunction> inner, std::array<bool, kMaxEdgeVertices> is_se3)
      : inner_(std::move(inner)), is_se3_(is_se3) {
    set_num_residuals(inner_->num_residuals());
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    if (jacobians == nullptr) return inner_->Evaluate(parameters, residuals, nullptr);
    const size_t num_blocks = parameter_block_sizes().size();
    std::array<std::array<double, 6 * 7>, kMaxEdgeVertices> ambient;
    std::array<double*, kMaxEdgeVertices> inner_jacobians{{nullptr, nullptr, nullptr}};
    for (size_t i = 0; i < num_blocks; ++i) {
      inner_jacobians[i] =
          (jacobians[i] != nullptr && is_se3_[i]) ? ambient[i].data() : jacobians[i];
    }
    if (!inner_->Evaluate(parameters, residuals, inner_jacobians.data())) return false;
    using RowMajor7 = Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor>;
    const int m = num_residuals();
    for (size_t i = 0; i < num_blocks; ++i) {
      if (jacobians[i] == nullptr || !is_se3_[i]) continue;
      const Eigen::Map<const RowMajor7> j_ambient(ambient[i].data(), m, 7);
      Eigen::Map<RowMajor7> j_lifted(jacobians[i], m, 7);
      Eigen::Matrix<double, 4, 3, Eigen::RowMajor> q_plus;
      quaternionRightPlusJacobian(parameters[i] + 3, q_plus.data());
      j_lifted.leftCols<3>() = j_ambient.leftCols<3>();
      j_lifted.middleCols<3>(3) = j_ambient.middleCols<4>(3) * q_plus;
      j_lifted.col(6).setZero();
    }
    return true;
  }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
  std::array<bool, kMaxEdgeVertices> is_se3_;
};

// ---- closed-form Jacobians for the two edge types that dominate real graphs -------------------

class SE2RelativeCost : public ceres::SizedCostFunction<3, 3, 3> {
 public:
  SE2RelativeCost(const Eigen::Vector3d& z, const Eigen::Matrix3d& sqrt_info)
      : z_(z), sqrt_info_(sqrt_info) {
    const double cz = std::cos(z[2]), sz = std::sin(z[2]);
    rz_t_ << cz, sz, -sz, cz;
  }

  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    const double* xi = x[0];
    const double* xj = x[1];
    Eigen::Vector3d e;
    se2RelativeError(xi, xj, z_.data(), e.data());
    Eigen::Map<Eigen::Vector3d> r(residuals);
    r = sqrt_info_ * e;
    if (jacobians == nullptr) return true;
    const double ci = std::cos(xi[2]), si = std::sin(xi[2]);
    Eigen::Matrix2d ri_t, dri_t;
    ri_t << ci, si, -si, ci;
    dri_t << -si, ci, -ci, -si;
    const Eigen::Vector2d d(xj[0] - xi[0], xj[1] - xi[1]);
    const Eigen::Matrix2d a = rz_t_ * ri_t;
    using RowMajor3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
    if (jacobians[0] != nullptr) {
      RowMajor3 j = RowMajor3::Zero();
      j.topLeftCorner<2, 2>() = -a;
      j.block<2, 1>(0, 2) = rz_t_ * dri_t * d;
      j(2, 2) = -1.0;
      Eigen::Map<RowMajor3> out(jacobians[0]);
      out = sqrt_info_ * j;
    }
    if (jacobians[1] != nullptr) {
      RowMajor3 j = RowMajor3::Zero();
      j.topLeftCorner<2, 2>() = a;
      j(2, 2) = 1.0;
      Eigen::Map<RowMajor3> out(jacobians[1]);
      out = sqrt_info_ * j;
    }
    return true;
  }

 private:
  Eigen::Vector3d z_;
  Eigen::Matrix3d sqrt_info_;
  Eigen::Matrix2d rz_t_;
};

class SE3RelativeCost : public ceres::SizedCostFunction<6, 7, 7> {
 public:
  SE3RelativeCost(const Quaterniond& qz_inv, const Vector3d& tz,
                  const Eigen::Matrix<double, 6, 6>& sqrt_info)
      : qz_inv_(qz_inv), rz_t_(qz_inv.toRotationMatrix()), tz_(tz), sqrt_info_(sqrt_info) {}

  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Vector3d> ti(x[0]), tj(x[1]);
    const Eigen::Map<const Quaterniond> qi(x[0] + 3), qj(x[1] + 3);
    const Matrix3d ri_t = qi.toRotationMatrix().transpose();
    const Vector3d tij = ri_t * (tj - ti);
    const Quaterniond qe = qz_inv_ * (qi.conjugate() * qj);
    const double sign = qe.w() < 0.0 ? -1.0 : 1.0;
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() = rz_t_ * (tij - tz_);
    e.tail<3>() = sign * qe.vec();
    Eigen::Map<Eigen::Matrix<double, 6, 1>> r(residuals);
    r = sqrt_info_ * e;
    if (jacobians == nullptr) return true;

    const Matrix3d a = rz_t_ * ri_t;
    const Vector3d v = qe.vec();
    const Matrix3d identity = Matrix3d::Identity();
    using RowMajor67 = Eigen::Matrix<double, 6, 7, Eigen::RowMajor>;
    Eigen::Matrix<double, 6, 6> j;
    if (jacobians[0] != nullptr) {
      j.setZero();
      j.block<3, 3>(0, 0) = -a;
      j.block<3, 3>(0, 3) = rz_t_ * skew(tij);
      // q_e(δ) = Exp(−Rzᵀδ) ⊗ q_e: left perturbation of the error quaternion.
      j.block<3, 3>(3, 3) = (-0.5 * sign) * (qe.w() * identity - skew(v)) * rz_t_;
      Eigen::Map<RowMajor67> out(jacobians[0]);
      out.leftCols<6>() = sqrt_info_ * j;
      out.col(6).setZero();
    }
    if (jacobians[1] != nullptr) {
      j.setZero();
      j.block<3, 3>(0, 0) = a;
      // q_e(δ) = q_e ⊗ Exp(δ): right perturbation.
      j.block<3, 3>(3, 3) = (0.5 * sign) * (qe.w() * identity + skew(v));
      Eigen::Map<RowMajor67> out(jacobians[1]);
      out.leftCols<6>() = sqrt_info_ * j;
      out.col(6).setZero();
    }
    return true;
  }

 private:
  Quaterniond qz_inv_;
  Matrix3d rz_t_;
  Vector3d tz_;
  Eigen::Matrix<double, 6, 6> sqrt_info_;
};

template <typename Functor, int kResiduals, int... kBlocks>
std::unique_ptr<ceres::CostFunction> autoDiff(Functor functor) {
  return std::make_unique<ceres::AutoDiffCostFunction<Functor, kResiduals, kBlocks...>>(
      new Functor(std::move(functor)));
}

std::unique_ptr<ceres::CostFunction> lifted(std::unique_ptr<ceres::CostFunction> inner,
                                            bool first_se3, bool second_se3 = false,
                                            bool third_se3 = false) {
  return std::make_unique<LiftedCost>(
      std::move(inner), std::array<bool, kMaxEdgeVertices>{{first_se3, second_se3, third_se3}});
}

void se3Measurement(const Eigen::VectorXd& m, Quaterniond* qz_inv, Vector3d* tz) {
  *tz = m.head<3>();
  *qz_inv = Quaterniond(m[6], m[3], m[4], m[5]).normalized().conjugate();
}

}  // namespace

// ---- manifolds ----------------------------------------------------------------------------------

bool SE3LiftedManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  for (int k = 0; k < 3; ++k) x_plus_delta[k] = x[k] + delta[k];
  const Eigen::Map<const Quaterniond> q(x + 3);
  Eigen::Map<Quaterniond> q_out(x_plus_delta + 3);
  q_out = (q * expRotation(delta + 3)).normalized();
  return true;
}

bool SE3LiftedManifold::PlusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> j(jacobian);
  j.setZero();
  j.topLeftCorner<6, 6>().setIdentity();
  return true;
}

bool SE3LiftedManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  for (int k = 0; k < 3; ++k) y_minus_x[k] = y[k] - x[k];
  const Eigen::Map<const Quaterniond> qx(x + 3), qy(y + 3);
  Eigen::Map<Vector3d> dtheta(y_minus_x + 3);
  dtheta = logRotation(qx.conjugate() * qy);
  return true;
}

bool SE3LiftedManifold::MinusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> j(jacobian);
  j.setZero();
  j.leftCols<6>().setIdentity();
  return true;
}

bool SE2Manifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  x_plus_delta[0] = x[0] + delta[0];
  x_plus_delta[1] = x[1] + delta[1];
  x_plus_delta[2] = wrapAngle(x[2] + delta[2]);
  return true;
}

bool SE2Manifold::PlusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobian);
  j.setIdentity();
  return true;
}

bool SE2Manifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  y_minus_x[0] = y[0] - x[0];
  y_minus_x[1] = y[1] - x[1];
  y_minus_x[2] = wrapAngle(y[2] - x[2]);
  return true;
}

bool SE2Manifold::MinusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobian);
  j.setIdentity();
  return true;
}

void quaternionRightPlusJacobian(const double* q_xyzw, double* jacobian_4x3) {
  // q ⊗ (½δ, 0): vector part ½(w δ + v × δ), scalar part −½ v·δ.
  const Vector3d v(q_xyzw[0], q_xyzw[1], q_xyzw[2]);
  const double w = q_xyzw[3];
  Eigen::Map<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> j(jacobian_4x3);
  j.topRows<3>() = 0.5 * (w * Matrix3d::Identity() + skew(v));
  j.row(3) = -0.5 * v.transpose();
}

std::unique_ptr<ceres::CostFunction> makeCostFunction(const PoseGraph::Edge& edge, bool analytic) {
  const Eigen::VectorXd& m = edge.measurement;
  const Eigen::MatrixXd& s = edge.sqrt_information;
  switch (edge.type) {
    case EdgeType::kSE3: {
      SE3RelativeFunctor f;
      se3Measurement(m, &f.qz_inv, &f.tz);
      f.sqrt_info = s;
      if (analytic) return std::make_unique<SE3RelativeCost>(f.qz_inv, f.tz, f.sqrt_info);
      return lifted(autoDiff<SE3RelativeFunctor, 6, 7, 7>(f), true, true);
    }
    case EdgeType::kSE3Scaled: {
      SE3ScaledFunctor f;
      se3Measurement(m, &f.qz_inv, &f.tz);
      f.sqrt_info = s;
      return lifted(autoDiff<SE3ScaledFunctor, 6, 7, 7, 1>(f), true, true, false);
    }
    case EdgeType::kPriorScale:
      return autoDiff<PriorPositionFunctor<1>, 1, 1>(PriorPositionFunctor<1>{m, s});
    case EdgeType::kScaleDifference:
      return autoDiff<ScalarDifferenceFunctor, 1, 1, 1>(ScalarDifferenceFunctor{m[0], s(0, 0)});
    case EdgeType::kSE2: {
      if (analytic) return std::make_unique<SE2RelativeCost>(m, s);
      return autoDiff<SE2RelativeFunctor, 3, 3, 3>(SE2RelativeFunctor{m, s});
    }
    case EdgeType::kSE3SE2:
      return lifted(autoDiff<SE3SE2Functor, 3, 7, 3>(SE3SE2Functor{m, s}), true, false);
    case EdgeType::kPriorSE3: {
      PriorSE3Functor f;
      se3Measurement(m, &f.qz_inv, &f.tz);
      f.sqrt_info = s;
      return lifted(autoDiff<PriorSE3Functor, 6, 7>(f), true);
    }
    case EdgeType::kPriorSE3XY:
      return lifted(autoDiff<PriorPositionFunctor<2>, 2, 7>(PriorPositionFunctor<2>{m, s}), true);
    case EdgeType::kPriorSE3XYZ:
      return lifted(autoDiff<PriorPositionFunctor<3>, 3, 7>(PriorPositionFunctor<3>{m, s}), true);
    case EdgeType::kPriorSE3Yaw:
      return lifted(autoDiff<PriorYawFunctor, 1, 7>(PriorYawFunctor{m[0], s(0, 0)}), true);
    case EdgeType::kPriorSE2:
      return autoDiff<PriorSE2Functor, 3, 3>(PriorSE2Functor{m, s});
    case EdgeType::kSE2PointXY:
      return autoDiff<SE2PointFunctor, 2, 3, 2>(SE2PointFunctor{m, s});
    case EdgeType::kSE3PointXY:
      return lifted(autoDiff<SE3PointFunctor, 2, 7, 2>(SE3PointFunctor{m, s}), true, false);
    case EdgeType::kSE2PointOnLine:
      return autoDiff<SE2PointOnLineFunctor, 1, 3, 3>(
          SE2PointOnLineFunctor{m.head<2>(), m.segment<2>(2), m[4], s(0, 0)});
    case EdgeType::kSE3PlanePair:
      return lifted(
          autoDiff<SE3PlanePairFunctor, 3, 7, 7>(SE3PlanePairFunctor{m.head<4>(), m.tail<4>(), s}),
          true, true);
    case EdgeType::kSE3YawDifference:
      return lifted(autoDiff<YawDifferenceFunctor, 1, 7, 7>(YawDifferenceFunctor{m[0], s(0, 0)}),
                    true, true);
    case EdgeType::kPriorPointXYZ:
      return autoDiff<PriorPositionFunctor<3>, 3, 3>(PriorPositionFunctor<3>{m, s});
    case EdgeType::kPointXYZGaussMarkov:
      return autoDiff<GaussMarkovFunctor, 3, 3, 3>(GaussMarkovFunctor{m[0], s});
    case EdgeType::kSE3PositionWithOffset:
      return lifted(autoDiff<PositionWithOffsetFunctor, 3, 7, 3>(PositionWithOffsetFunctor{m, s}),
                    true, false);
  }
  return nullptr;
}

std::unique_ptr<ceres::LossFunction> makeLossFunction(const RobustKernel& kernel) {
  switch (kernel.type) {
    case RobustKernelType::kHuber:
      return std::make_unique<ceres::HuberLoss>(kernel.width);
    case RobustKernelType::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(kernel.width);
    case RobustKernelType::kNone:
      break;
  }
  return nullptr;
}

}  // namespace osm_graph_slam::graph_detail
