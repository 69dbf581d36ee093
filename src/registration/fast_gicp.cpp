// Our multi-threaded Generalized-ICP (Segal et al. 2009, plane-to-plane): per-point covariances
// from k nearest neighbours (nanoflann KD-tree), distribution-to-distribution Mahalanobis cost
// minimised by Levenberg-Marquardt on SE(3); correspondences, covariances and the normal
// equations are computed in parallel with TBB.
#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <nanoflann.hpp>
#include <vector>

#include "registration_backends.h"

namespace osm_graph_slam::detail {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

struct PointAdaptor {
  const std::vector<Eigen::Vector3f>* points = nullptr;
  size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return (*points)[i][dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointAdaptor>,
                                                   PointAdaptor, 3, uint32_t>;

/// A cloud prepared for GICP: finite points, KD-tree and regularised covariances.
struct PreparedCloud {
  PointCloudConstPtr source;  ///< the cloud this was built from (to recognise it again)
  std::vector<Eigen::Vector3f> points;
  std::vector<Mat3> covariances;
  PointAdaptor adaptor;
  std::unique_ptr<KdTree> tree;
};

std::shared_ptr<PreparedCloud> prepare(const PointCloudConstPtr& cloud, int k, double epsilon) {
  auto prepared = std::make_shared<PreparedCloud>();
  prepared->source = cloud;
  if (!cloud) return prepared;
  prepared->points.reserve(cloud->size());
  for (const auto& p : cloud->points) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) {
      prepared->points.emplace_back(p.x, p.y, p.z);
    }
  }
  const size_t n = prepared->points.size();
  if (n == 0) return prepared;
  prepared->adaptor.points = &prepared->points;
  prepared->tree = std::make_unique<KdTree>(3, prepared->adaptor,
                                            nanoflann::KDTreeSingleIndexAdaptorParams(10));
  prepared->covariances.resize(n);
  const size_t kk = std::min<size_t>(std::max(k, 3), n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<uint32_t> idx(kk);
    std::vector<float> dist(kk);
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const size_t found = prepared->tree->knnSearch(prepared->points[i].data(), kk, idx.data(),
                                                     dist.data());
      Vec3 mean = Vec3::Zero();
      Mat3 second = Mat3::Zero();
      for (size_t j = 0; j < found; ++j) {
        const Vec3 q = prepared->points[idx[j]].cast<double>();
        mean += q;
        second += q * q.transpose();
      }
      Mat3 cov = Mat3::Identity() * epsilon;
      if (found >= 3) {
        mean /= double(found);
        cov = (second - double(found) * mean * mean.transpose()) / double(found);
        // Plane model: the smallest spread becomes epsilon, the two others 1 (GICP paper §3.2).
        Eigen::SelfAdjointEigenSolver<Mat3> eig;
        eig.computeDirect(cov);
        const Vec3 values(epsilon, 1.0, 1.0);
        cov = eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
      }
      prepared->covariances[i] = cov;
    }
  });
  return prepared;
}

Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

/// Applies the update delta = (translation, rotation vector) on the left of T.
Eigen::Isometry3d applyUpdate(const Vec6& delta, const Eigen::Isometry3d& t) {
  Eigen::Isometry3d update = Eigen::Isometry3d::Identity();
  const Vec3 phi = delta.tail<3>();
  const double angle = phi.norm();
  if (angle > 1e-12) update.linear() = Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
  update.translation() = delta.head<3>();
  Eigen::Isometry3d out = update * t;
  out.linear() = Eigen::Quaterniond(out.linear()).normalized().toRotationMatrix();
  return out;
}

struct Correspondence {
  int target = -1;
  Mat3 information;  ///< (C_target + R C_source R^T)^-1
};

struct NormalEquations {
  Mat6 h = Mat6::Zero();
  Vec6 b = Vec6::Zero();
  double cost = 0.0;
  double squared_distance = 0.0;
  int inliers = 0;
};

class FastGicp : public Registration {
 public:
  explicit FastGicp(const RegistrationParams& params)
      : params_(params),
        arena_(params.num_threads > 0 ? params.num_threads : tbb::task_arena::automatic) {}

  std::string name() const override { return "fast_gicp"; }

  void setTarget(const PointCloudConstPtr& target) override {
    // A scan that becomes the new keyframe was just the source: reuse its tree and covariances.
    if (last_source_ && target && last_source_->source == target) {
      target_ = last_source_;
      return;
    }
    arena_.execute([&] { target_ = prepare(target, params_.k_correspondences, epsilon()); });
  }

  RegistrationResult align(const PointCloudConstPtr& source,
                           const Eigen::Isometry3d& guess) override {
    const auto start = std::chrono::steady_clock::now();
    RegistrationResult result;
    result.transform = guess;
    arena_.execute([&] { result = alignImpl(source, guess); });
    if (!result.converged) result.transform = guess;
    result.time_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  }

 private:
  double epsilon() const { return params_.gicp_covariance_epsilon; }
  size_t minPoints() const { return static_cast<size_t>(std::max(params_.min_correspondences, 6)); }

  RegistrationResult alignImpl(const PointCloudConstPtr& source, const Eigen::Isometry3d& guess) {
    RegistrationResult result;
    result.transform = guess;
    if (!target_ || target_->points.size() < minPoints()) {
      result.message = "fast_gicp: target has fewer than " + std::to_string(minPoints()) +
                       " valid points";
      return result;
    }
    last_source_ = prepare(source, params_.k_correspondences, epsilon());
    const PreparedCloud& src = *last_source_;
    if (src.points.size() < minPoints()) {
      result.message = "fast_gicp: source has fewer than " + std::to_string(minPoints()) +
                       " valid points";
      return result;
    }
    if (!guess.matrix().allFinite()) {
      result.message = "fast_gicp: initial guess is not finite";
      return result;
    }

    Eigen::Isometry3d t = guess;
    std::vector<Correspondence> corr(src.points.size());
    double lambda = 1e-6;
    NormalEquations eq;
    for (int iter = 0; iter < params_.max_iterations; ++iter) {
      result.iterations = iter + 1;
      updateCorrespondences(src, t, corr);
      eq = linearise(src, t, corr, true);
      if (eq.inliers < params_.min_correspondences) {
        result.message = "fast_gicp: only " + std::to_string(eq.inliers) +
                         " correspondences within " +
                         std::to_string(params_.max_correspondence_distance) + " m";
        return result;
      }
      // Levenberg-Marquardt on the fixed correspondences: accept a step only if it lowers the cost.
      Vec6 delta = Vec6::Zero();
      bool accepted = false;
      for (int attempt = 0; attempt < 10 && !accepted; ++attempt) {
        Mat6 damped = eq.h;
        damped.diagonal().array() += lambda * eq.h.diagonal().array().max(1e-9);
        delta = damped.ldlt().solve(-eq.b);
        if (!delta.allFinite()) break;
        const Eigen::Isometry3d candidate = applyUpdate(delta, t);
        const double cost = linearise(src, candidate, corr, false).cost;
        if (cost <= eq.cost) {
          t = candidate;
          lambda = std::max(lambda / 10.0, 1e-12);
          accepted = true;
        } else {
          lambda *= 10.0;
        }
      }
      const bool small_step = delta.head<3>().norm() < params_.transformation_epsilon &&
                              delta.tail<3>().norm() < params_.transformation_epsilon;
      if (!accepted || small_step) {
        // No descent left (or a negligible step): we are at the minimum for these
        // correspondences; converged if they no longer move either.
        result.converged = true;
        break;
      }
    }
    updateCorrespondences(src, t, corr);
    eq = linearise(src, t, corr, false);
    result.transform = t;
    result.fitness = eq.inliers > 0 ? eq.squared_distance / eq.inliers
                                    : std::numeric_limits<double>::infinity();
    if (!result.converged) {
      result.message = "fast_gicp: did not converge within " +
                       std::to_string(params_.max_iterations) + " iterations";
    } else if (eq.inliers < params_.min_correspondences) {
      result.converged = false;
      result.message = "fast_gicp: too few correspondences at the solution";
    }
    return result;
  }

  void updateCorrespondences(const PreparedCloud& src, const Eigen::Isometry3d& t,
                             std::vector<Correspondence>& corr) const {
    const double max_sq = params_.max_correspondence_distance * params_.max_correspondence_distance;
    const Mat3 r = t.linear();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, src.points.size(), 512),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          const Eigen::Vector3f p = (t * src.points[i].cast<double>()).cast<float>();
                          uint32_t index = 0;
                          float dist_sq = 0.0f;
                          const size_t found =
                              target_->tree->knnSearch(p.data(), 1, &index, &dist_sq);
                          if (found == 0 || dist_sq > max_sq) {
                            corr[i].target = -1;
                            continue;
                          }
                          corr[i].target = static_cast<int>(index);
                          const Mat3 combined = target_->covariances[index] +
                                                r * src.covariances[i] * r.transpose();
                          corr[i].information = combined.inverse();
                        }
                      });
  }

  /// Cost (and, when with_derivatives, Gauss-Newton normal equations) for fixed correspondences.
  NormalEquations linearise(const PreparedCloud& src, const Eigen::Isometry3d& t,
                            const std::vector<Correspondence>& corr, bool with_derivatives) const {
    tbb::combinable<NormalEquations> partial;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, src.points.size(), 512),
        [&](const tbb::blocked_range<size_t>& range) {
          NormalEquations& acc = partial.local();
          Eigen::Matrix<double, 3, 6> j;
          for (size_t i = range.begin(); i != range.end(); ++i) {
            if (corr[i].target < 0) continue;
            const Vec3 p = t * src.points[i].cast<double>();
            const Vec3 residual = target_->points[corr[i].target].cast<double>() - p;
            const Mat3& info = corr[i].information;
            acc.cost += residual.dot(info * residual);
            acc.squared_distance += residual.squaredNorm();
            ++acc.inliers;
            if (!with_derivatives) continue;
            // d(residual)/d(delta) for p' = exp(phi) p + rho: [-I, [p]x].
            j.leftCols<3>() = -Mat3::Identity();
            j.rightCols<3>() = skew(p);
            const Eigen::Matrix<double, 6, 3> jt_info = j.transpose() * info;
            acc.h.noalias() += jt_info * j;
            acc.b.noalias() += jt_info * residual;
          }
        });
    NormalEquations total;
    partial.combine_each([&](const NormalEquations& e) {
      total.h += e.h;
      total.b += e.b;
      total.cost += e.cost;
      total.squared_distance += e.squared_distance;
      total.inliers += e.inliers;
    });
    return total;
  }

  RegistrationParams params_;
  tbb::task_arena arena_;
  std::shared_ptr<PreparedCloud> target_;
  std::shared_ptr<PreparedCloud> last_source_;
};

}  // namespace

std::unique_ptr<Registration> makeFastGicp(const RegistrationParams& params) {
  return std::make_unique<FastGicp>(params);
}

}  // namespace osm_graph_slam::detail
