#include "osm_graph_slam/radar/radar_registration.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <nanoflann.hpp>

#include "osm_graph_slam/radar/radar_motion.h"

namespace osm_graph_slam::radar {
namespace {

struct PointsAdaptor {
  const std::vector<Eigen::Vector2d>* points = nullptr;
  size_t kdtree_get_point_count() const { return points->size(); }
  double kdtree_get_pt(size_t i, size_t dim) const { return (*points)[i][int(dim)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};
using KdTree2 =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointsAdaptor>,
                                        PointsAdaptor, 2, uint32_t>;

Eigen::Isometry2d makePose(double x, double y, double yaw) {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() = Eigen::Rotation2Dd(yaw).toRotationMatrix();
  T.translation() << x, y;
  return T;
}

/// The translation information once the yaw is marginalised (Schur complement): a single wall,
/// or parallel walls without poles, leave one direction almost free, so its eigenvalue ratio
/// collapses (measured 2.6e-4 for one noisy wall; 0.1-1 for a street corner). A fixed floor on
/// the smallest eigenvalue misses it: noisy normals lift that to ~0.05.
bool constrainsTranslation(const Eigen::Matrix3d& H, double min_ratio) {
  if (H(2, 2) <= 1e-12) return false;
  const Eigen::Matrix2d t =
      H.topLeftCorner<2, 2>() - H.topRightCorner<2, 1>() * H.bottomLeftCorner<1, 2>() / H(2, 2);
  const Eigen::Vector2d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(t).eigenvalues();
  return ev(1) > 1e-9 && ev(0) >= min_ratio * ev(1);
}

}  // namespace

std::vector<Eigen::Vector2d> compensatedPoints(const std::vector<RadarFeature>& features,
                                               const Eigen::Vector3d& velocity, double t_ref,
                                               double beta, bool clockwise,
                                               bool motion_compensation) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(features.size());
  const Eigen::Vector2d v = velocity.head<2>();
  for (const RadarFeature& f : features) {
    const Eigen::Vector2d dir = beamDirection(f.azimuth, clockwise);
    const Eigen::Vector2d p = dopplerCorrectedRange(f.range, dir, v, beta) * dir;
    // The sensor at the row's time, seen from the sensor at t_ref: exp((t - t_ref) w).
    out.push_back(motion_compensation ? Eigen::Vector2d(se2Exp(velocity, f.time - t_ref) * p) : p);
  }
  return out;
}

struct PlanarPointMap::Index {
  std::vector<Eigen::Vector2d> points;
  std::vector<Eigen::Vector2d> normals;  ///< zero: no line here, point-to-point
  PointsAdaptor adaptor;
  std::unique_ptr<KdTree2> tree;
};

PlanarPointMap::PlanarPointMap() : index_(std::make_unique<Index>()) {}
PlanarPointMap::~PlanarPointMap() = default;
PlanarPointMap::PlanarPointMap(PlanarPointMap&&) noexcept = default;
PlanarPointMap& PlanarPointMap::operator=(PlanarPointMap&&) noexcept = default;

size_t PlanarPointMap::size() const {
  return index_->points.size();
}
const std::vector<Eigen::Vector2d>& PlanarPointMap::points() const {
  return index_->points;
}

void PlanarPointMap::build(std::vector<Eigen::Vector2d> points,
                           const RadarRegistrationParams& params) {
  Index& ix = *index_;
  ix.points = std::move(points);
  ix.normals.assign(ix.points.size(), Eigen::Vector2d::Zero());
  ix.adaptor.points = &ix.points;
  ix.tree = std::make_unique<KdTree2>(2, ix.adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  ix.tree->buildIndex();
  const size_t k = size_t(std::max(3, params.normal_neighbours));
  std::vector<uint32_t> idx(k);
  std::vector<double> d2(k);
  const double max_d2 = 4.0 * params.max_correspondence * params.max_correspondence;
  for (size_t i = 0; i < ix.points.size(); ++i) {
    const size_t n = ix.tree->knnSearch(ix.points[i].data(), k, idx.data(), d2.data());
    if (n < 3 || d2[n - 1] > max_d2) continue;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (size_t j = 0; j < n; ++j) mean += ix.points[idx[j]];
    mean /= double(n);
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (size_t j = 0; j < n; ++j) {
      const Eigen::Vector2d d = ix.points[idx[j]] - mean;
      cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    const Eigen::Vector2d ev = es.eigenvalues();  // ascending
    if (ev(1) > 1e-9 && ev(0) <= params.max_line_ratio * ev(1))
      ix.normals[i] = es.eigenvectors().col(0);
  }
}

RadarAlignment PlanarPointMap::align(const std::vector<Eigen::Vector2d>& points,
                                     const Eigen::Isometry2d& guess,
                                     const RadarRegistrationParams& params) const {
  RadarAlignment out;
  out.pose = guess;
  const Index& ix = *index_;
  if (!ix.tree || ix.points.empty() || points.empty()) return out;
  double x = guess.translation().x(), y = guess.translation().y();
  double yaw = std::atan2(guess.linear()(1, 0), guess.linear()(0, 0));
  const double max_d2 = params.max_correspondence * params.max_correspondence;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int it = 0; it < std::max(1, params.iterations); ++it) {
    const Eigen::Isometry2d T = makePose(x, y, yaw);
    const double c = std::cos(yaw), s = std::sin(yaw);
    H.setZero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    int used = 0;
    double sum_sq = 0.0;
    for (const Eigen::Vector2d& p : points) {
      const Eigen::Vector2d q = T * p;
      uint32_t j;
      double d2;
      if (ix.tree->knnSearch(q.data(), 1, &j, &d2) < 1 || d2 > max_d2) continue;
      const Eigen::Vector2d dq_dyaw(-s * p.x() - c * p.y(), c * p.x() - s * p.y());
      const Eigen::Vector2d& n = ix.normals[j];
      auto accumulate = [&](const Eigen::Vector3d& J, double e) {
        const double w = std::abs(e) <= params.huber ? 1.0 : params.huber / std::abs(e);
        H += w * J * J.transpose();
        g += w * J * e;
        sum_sq += w * e * e;
      };
      const Eigen::Vector2d diff = q - ix.points[j];
      if (n.squaredNorm() > 0.5) {
        accumulate(Eigen::Vector3d(n.x(), n.y(), n.dot(dq_dyaw)), n.dot(diff));
      } else {
        accumulate(Eigen::Vector3d(1.0, 0.0, dq_dyaw.x()), diff.x());
        accumulate(Eigen::Vector3d(0.0, 1.0, dq_dyaw.y()), diff.y());
      }
      ++used;
    }
    out.correspondences = used;
    out.rms = used > 0 ? std::sqrt(sum_sq / used) : 0.0;
    if (used < params.min_correspondences) return out;
    if (!constrainsTranslation(H, params.min_translation_ratio)) return out;
    const Eigen::Vector3d delta = -H.ldlt().solve(g);
    x += delta.x();
    y += delta.y();
    yaw += delta.z();
    if (delta.head<2>().norm() < 1e-4 && std::abs(delta.z()) < 1e-5) break;
  }
  out.ok = true;
  out.pose = makePose(x, y, yaw);
  const double sigma = std::max(out.rms, 0.05);
  out.information = H / (sigma * sigma);
  return out;
}

void RadarLocalMap::addKeyframe(const Eigen::Isometry2d& pose,
                                const std::vector<Eigen::Vector2d>& points) {
  keyframes_.push_back({pose, points});
  while (int(keyframes_.size()) > std::max(1, params_.submap_keyframes)) keyframes_.pop_front();
  std::vector<Eigen::Vector2d> all;
  for (const Keyframe& k : keyframes_)
    for (const Eigen::Vector2d& p : k.points) all.push_back(k.pose * p);
  map_.build(std::move(all), params_);
}

}  // namespace osm_graph_slam::radar
