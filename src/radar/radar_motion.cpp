#include "osm_graph_slam/radar/radar_motion.h"

#include <Eigen/Dense>
#include <cmath>
#include <random>

namespace osm_graph_slam::radar {
namespace {

/// V(theta) of the SE(2) exponential: translation = V * v * dt.
Eigen::Matrix2d leftJacobian(double theta) {
  Eigen::Matrix2d V;
  if (std::abs(theta) < 1e-9) {
    V.setIdentity();
    return V;
  }
  const double a = std::sin(theta) / theta, b = (1.0 - std::cos(theta)) / theta;
  V << a, -b, b, a;
  return V;
}

Eigen::Vector2d correctedPoint(double range, const Eigen::Vector2d& dir, const Eigen::Vector2d& v,
                               double beta) {
  return dopplerCorrectedRange(range, dir, v, beta) * dir;
}

/// Rigid transform p2 = T p1 from two point pairs (no time, no Doppler): the RANSAC hypothesis.
bool rigidFromTwo(const Eigen::Vector2d& a1, const Eigen::Vector2d& b1, const Eigen::Vector2d& a2,
                  const Eigen::Vector2d& b2, double tolerance, Eigen::Isometry2d& T) {
  const Eigen::Vector2d d1 = b1 - a1, d2 = b2 - a2;
  if (d1.norm() < 1.0 || std::abs(d1.norm() - d2.norm()) > tolerance) return false;
  const double angle = std::atan2(d2.y(), d2.x()) - std::atan2(d1.y(), d1.x());
  T.setIdentity();
  T.linear() = Eigen::Rotation2Dd(angle).toRotationMatrix();
  T.translation() = 0.5 * (a2 + b2) - T.linear() * 0.5 * (a1 + b1);
  return true;
}

std::vector<int> inliersOf(const std::vector<RadarCorrespondence>& cs, const Eigen::Vector3d& w,
                           double beta, double threshold, double* rms) {
  std::vector<int> in;
  double sum = 0.0;
  for (size_t i = 0; i < cs.size(); ++i) {
    const double e = correspondenceError(cs[i], w, beta).squaredNorm();
    if (e < threshold * threshold) {
      in.push_back(int(i));
      sum += e;
    }
  }
  if (rms) *rms = in.empty() ? 0.0 : std::sqrt(sum / in.size());
  return in;
}

}  // namespace

Eigen::Isometry2d se2Exp(const Eigen::Vector3d& twist, double dt) {
  const double theta = twist.z() * dt;
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() = Eigen::Rotation2Dd(theta).toRotationMatrix();
  T.translation() = leftJacobian(theta) * twist.head<2>() * dt;
  return T;
}

Eigen::Vector3d se2Log(const Eigen::Isometry2d& T) {
  const double theta = std::atan2(T.linear()(1, 0), T.linear()(0, 0));
  Eigen::Vector3d xi;
  xi.head<2>() = leftJacobian(theta).inverse() * T.translation();
  xi.z() = theta;
  return xi;
}

double dopplerCorrectedRange(double measured_range, const Eigen::Vector2d& dir,
                             const Eigen::Vector2d& linear_velocity, double beta) {
  return measured_range + beta * linear_velocity.dot(dir);
}

Eigen::Vector2d correspondenceError(const RadarCorrespondence& c, const Eigen::Vector3d& w,
                                    double beta) {
  const Eigen::Vector2d v = w.head<2>();
  const Eigen::Vector2d p1 = correctedPoint(c.range1, c.dir1, v, beta);
  const Eigen::Vector2d p2 = correctedPoint(c.range2, c.dir2, v, beta);
  return p2 - se2Exp(w, -(c.t2 - c.t1)) * p1;
}

Eigen::Vector3d refineVelocity(const std::vector<RadarCorrespondence>& cs,
                               const std::vector<int>& use, const Eigen::Vector3d& w0, double beta,
                               int iterations) {
  Eigen::Vector3d w = w0;
  const double h[3] = {1e-5, 1e-5, 1e-6};
  for (int it = 0; it < iterations; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (int i : use) {
      const RadarCorrespondence& c = cs[size_t(i)];
      const Eigen::Vector2d e = correspondenceError(c, w, beta);
      Eigen::Matrix<double, 2, 3> J;  // de/dw (central differences; eq. 7.6's G_m)
      for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d wp = w, wm = w;
        wp[k] += h[k];
        wm[k] -= h[k];
        J.col(k) =
            (correspondenceError(c, wp, beta) - correspondenceError(c, wm, beta)) / (2 * h[k]);
      }
      H += J.transpose() * J;
      g += J.transpose() * e;
    }
    if (H.determinant() < 1e-12) break;
    const Eigen::Vector3d delta = -H.ldlt().solve(g);
    w += delta;
    if (delta.head<2>().norm() < 1e-7 && std::abs(delta.z()) < 1e-9) break;
  }
  return w;
}

MotionEstimate estimateVelocity(std::vector<RadarCorrespondence> cs, const MotionEstimatorParams& p,
                                const SweepTimes& sweeps, const Eigen::Vector3d& initial_velocity) {
  MotionEstimate out;
  if (!p.motion_compensation) {
    for (RadarCorrespondence& c : cs) {
      c.t1 = sweeps.t_ref1;
      c.t2 = sweeps.t_ref2;
    }
  }
  const double beta = p.doppler_correction ? p.doppler_beta : 0.0;
  if (cs.size() < 2 || int(cs.size()) < p.min_inliers) return out;
  std::mt19937 rng(p.seed);
  std::uniform_int_distribution<size_t> pick(0, cs.size() - 1);
  const Eigen::Vector2d v0 = initial_velocity.head<2>();
  std::vector<int> best;
  Eigen::Vector3d best_w = initial_velocity;
  for (int it = 0; it < p.ransac_iterations; ++it) {
    const size_t i = pick(rng), j = pick(rng);
    if (i == j) continue;
    const RadarCorrespondence &a = cs[i], &b = cs[j];
    Eigen::Isometry2d T;
    if (!rigidFromTwo(correctedPoint(a.range1, a.dir1, v0, beta),
                      correctedPoint(b.range1, b.dir1, v0, beta),
                      correctedPoint(a.range2, a.dir2, v0, beta),
                      correctedPoint(b.range2, b.dir2, v0, beta), 2.0 * p.inlier_threshold, T))
      continue;
    const double dt = 0.5 * ((a.t2 - a.t1) + (b.t2 - b.t1));
    if (dt <= 1e-6) continue;
    const Eigen::Vector3d w = -se2Log(T) / dt;
    std::vector<int> in = inliersOf(cs, w, beta, p.inlier_threshold, nullptr);
    if (in.size() > best.size()) {
      best = std::move(in);
      best_w = w;
    }
  }
  if (int(best.size()) < p.min_inliers) return out;
  // Refine on the inliers, re-select them with the refined motion, refine again.
  Eigen::Vector3d w = best_w;
  for (int round = 0; round < 3; ++round) {
    w = refineVelocity(cs, best, w, beta, p.gauss_newton_iterations);
    std::vector<int> in = inliersOf(cs, w, beta, p.inlier_threshold, &out.rms_error);
    if (int(in.size()) < p.min_inliers) return out;
    const bool same = in == best;
    best = std::move(in);
    if (same) break;
  }
  out.ok = true;
  out.velocity = w;
  out.inliers = std::move(best);
  return out;
}

}  // namespace osm_graph_slam::radar
