#include "osm_graph_slam/lines/line_segment_extractor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>
#include <unordered_map>

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// Weighted 2D points in structure-of-arrays form (the RANSAC scoring loop vectorises).
struct WeightedPoints {
  std::vector<float> x, y, w;
  size_t size() const { return x.size(); }
  void push(float px, float py, float pw) {
    x.push_back(px);
    y.push_back(py);
    w.push_back(pw);
  }
};

/// Finite and within +-1000 km (grid keys must not overflow).
bool usable(const Eigen::Vector2d& p) {
  return p.allFinite() && p.cwiseAbs().maxCoeff() < 1e6;
}

/// Merges coincident points on a grid (centroid, weight = count); drops non-finite points.
WeightedPoints mergeOnGrid(const std::vector<Eigen::Vector2d>& pts, double res) {
  WeightedPoints out;
  if (res <= 0.0) {
    for (const auto& p : pts)
      if (usable(p)) out.push(float(p.x()), float(p.y()), 1.0f);
    return out;
  }
  struct Acc {
    double x = 0, y = 0;
    int n = 0;
  };
  std::unordered_map<uint64_t, size_t> cell_of;
  std::vector<Acc> acc;
  cell_of.reserve(pts.size());
  for (const auto& p : pts) {
    if (!usable(p)) continue;
    const int64_t cx = int64_t(std::floor(p.x() / res)), cy = int64_t(std::floor(p.y() / res));
    const uint64_t key = (uint64_t(cx & 0xffffffff) << 32) | uint64_t(cy & 0xffffffff);
    auto it = cell_of.emplace(key, acc.size()).first;
    if (it->second == acc.size()) acc.emplace_back();
    Acc& a = acc[it->second];
    a.x += p.x();
    a.y += p.y();
    ++a.n;
  }
  for (const Acc& a : acc) out.push(float(a.x / a.n), float(a.y / a.n), float(a.n));
  return out;
}

struct Line {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d dir = Eigen::Vector2d::UnitX();  // unit
};

/// Weighted total least squares line of a subset.
Line fitLine(const WeightedPoints& p, const std::vector<int>& idx) {
  double sw = 0, mx = 0, my = 0;
  for (int i : idx) {
    sw += p.w[i];
    mx += p.w[i] * p.x[i];
    my += p.w[i] * p.y[i];
  }
  mx /= sw;
  my /= sw;
  double sxx = 0, sxy = 0, syy = 0;
  for (int i : idx) {
    const double dx = p.x[i] - mx, dy = p.y[i] - my;
    sxx += p.w[i] * dx * dx;
    sxy += p.w[i] * dx * dy;
    syy += p.w[i] * dy * dy;
  }
  const double angle = 0.5 * std::atan2(2.0 * sxy, sxx - syy);  // principal axis
  return {{mx, my}, {std::cos(angle), std::sin(angle)}};
}

/// One round of Algorithm 3.1 works on the still-active points.
class RansacLines {
 public:
  RansacLines(const WeightedPoints& pts, const LineSegmentExtractorParams& params)
      : pts_(pts), p_(params), rng_(params.seed), active_(pts.size(), 1) {}

  std::vector<LineSegment2> run(LineSegmentStats& stats) {
    std::vector<LineSegment2> segments;
    int rejects = 0;
    while (int(segments.size()) < p_.max_segments && rejects < p_.max_consecutive_rejects) {
      compact();
      if (int(ax_.size()) <= p_.min_cluster_size || ax_.size() < 2) break;
      ++stats.lines_tried;
      Line hyp;
      if (!bestHypothesis(hyp, stats)) break;  // no line has enough inliers left
      std::vector<int> inliers = inliersOf(hyp);
      if (int(inliers.size()) < p_.min_cluster_size) break;  // the best line is too weak already
      std::vector<int> cluster = largestCluster(std::move(inliers), hyp);
      if (int(cluster.size()) < p_.min_cluster_size) {
        remove(cluster);
        ++rejects;
        continue;
      }
      if (p_.refine) cluster = refineCluster(cluster);
      LineSegment2 seg = segmentOf(cluster);
      remove(cluster);
      if (seg.length() < p_.min_segment_length) {
        ++rejects;
        continue;
      }
      rejects = 0;
      segments.push_back(seg);
    }
    return segments;
  }

 private:
  /// Sampling cells of every point, computed once: rounds only filter this order (no re-sort).
  void sortByCell() {
    const double cell = std::max(1e-3, p_.sample_cell);
    std::vector<std::pair<uint64_t, int>> keyed(pts_.size());
    for (size_t i = 0; i < pts_.size(); ++i) {
      const int64_t cx = int64_t(std::floor(pts_.x[i] / cell));
      const int64_t cy = int64_t(std::floor(pts_.y[i] / cell));
      keyed[i] = {(uint64_t(cx & 0xffffffff) << 32) | uint64_t(cy & 0xffffffff), int(i)};
    }
    std::sort(keyed.begin(), keyed.end());
    sorted_key_.resize(keyed.size());
    sorted_id_.resize(keyed.size());
    for (size_t i = 0; i < keyed.size(); ++i) {
      sorted_key_[i] = keyed[i].first;
      sorted_id_[i] = keyed[i].second;
    }
  }

  /// Active points in contiguous arrays (cell order), each with its cell's range; and a strided
  /// subset of at most kScoreSubset points on which hypotheses are ranked.
  void compact() {
    if (sorted_id_.size() != pts_.size()) sortByCell();
    ax_.clear();
    ay_.clear();
    aw_.clear();
    aid_.clear();
    std::vector<uint64_t> keys;
    for (size_t k = 0; k < sorted_id_.size(); ++k) {
      const int i = sorted_id_[k];
      if (!active_[i]) continue;
      ax_.push_back(pts_.x[i]);
      ay_.push_back(pts_.y[i]);
      aw_.push_back(pts_.w[i]);
      aid_.push_back(i);
      keys.push_back(sorted_key_[k]);
    }
    const size_t n = ax_.size();
    cell_begin_.resize(n);
    cell_end_.resize(n);
    for (size_t b = 0, i = 0; i <= n; ++i) {
      if (i == n || keys[i] != keys[b]) {
        for (size_t j = b; j < i; ++j) {
          cell_begin_[j] = int(b);
          cell_end_[j] = int(i);
        }
        b = i;
      }
    }
    const size_t stride = std::max<size_t>(1, (n + kScoreSubset - 1) / kScoreSubset);
    sx_.clear();
    sy_.clear();
    sw_.clear();
    for (size_t i = 0; i < n; i += stride) {
      sx_.push_back(ax_[i]);
      sy_.push_back(ay_[i]);
      sw_.push_back(int32_t(aw_[i]));
    }
  }

  /// Weighted inlier count on the scoring subset. Integer weights (point counts) keep the
  /// reduction exact, so the compiler vectorises the loop without -ffast-math.
  int32_t score(float nx, float ny, float c) const {
    const float thr = float(p_.distance_threshold);
    int32_t s = 0;
    const size_t n = sx_.size();
    const float* x = sx_.data();
    const float* y = sy_.data();
    const int32_t* w = sw_.data();
    for (size_t i = 0; i < n; ++i) {
      const float d = std::abs(nx * x[i] + ny * y[i] - c);
      s += d < thr ? w[i] : 0;
    }
    return s;
  }

  bool bestHypothesis(Line& best, LineSegmentStats& stats) {
    const int n = int(ax_.size());
    std::uniform_int_distribution<int> any(0, n - 1);
    int32_t best_score = -1;
    for (int it = 0; it < p_.max_iterations; ++it) {
      const int pa = any(rng_);
      int pb;
      if (cell_end_[pa] - cell_begin_[pa] >= 2) {
        std::uniform_int_distribution<int> local(cell_begin_[pa], cell_end_[pa] - 1);
        pb = local(rng_);
        if (pb == pa) pb = (pb + 1 < cell_end_[pa]) ? pb + 1 : cell_begin_[pa];
      } else {
        pb = any(rng_);
      }
      const int a = pa, b = pb;
      const float dx = ax_[b] - ax_[a], dy = ay_[b] - ay_[a];
      const float len = std::sqrt(dx * dx + dy * dy);
      if (!(len > 1e-4f)) continue;
      const float nx = -dy / len, ny = dx / len;
      const int32_t s = score(nx, ny, nx * ax_[a] + ny * ay_[a]);
      ++stats.hypotheses;
      if (s > best_score) {
        best_score = s;
        best.point = {ax_[a], ay_[a]};
        best.dir = {dx / len, dy / len};
      }
    }
    return best_score >= 0;
  }

  /// Active-array indices within the inlier distance of the line.
  std::vector<int> inliersOf(const Line& l) const {
    std::vector<int> in;
    const double nx = -l.dir.y(), ny = l.dir.x(), c = nx * l.point.x() + ny * l.point.y();
    for (size_t i = 0; i < ax_.size(); ++i)
      if (std::abs(nx * ax_[i] + ny * ay_[i] - c) < p_.distance_threshold) in.push_back(int(i));
    return in;
  }

  /// Inliers are (nearly) collinear, so Euclidean clustering reduces to splitting the sorted
  /// projections at gaps wider than the tolerance. Returns the heaviest cluster (active indices).
  std::vector<int> largestCluster(std::vector<int> in, const Line& l) const {
    if (in.empty()) return in;
    std::vector<std::pair<double, int>> proj(in.size());
    for (size_t k = 0; k < in.size(); ++k) {
      const int i = in[k];
      proj[k] = {(ax_[i] - l.point.x()) * l.dir.x() + (ay_[i] - l.point.y()) * l.dir.y(), i};
    }
    std::sort(proj.begin(), proj.end());
    size_t best_b = 0, best_e = 0, b = 0;
    double best_w = -1.0, w = 0.0;
    for (size_t k = 0; k <= proj.size(); ++k) {
      if (k == proj.size() || (k > b && proj[k].first - proj[k - 1].first > p_.cluster_tolerance)) {
        if (w > best_w) {
          best_w = w;
          best_b = b;
          best_e = k;
        }
        b = k;
        w = 0.0;
      }
      if (k < proj.size()) w += aw_[proj[k].second];
    }
    std::vector<int> cluster;
    for (size_t k = best_b; k < best_e; ++k) cluster.push_back(proj[k].second);
    return cluster;
  }

  Line fitActive(const std::vector<int>& cluster) const {
    WeightedPoints sub;
    std::vector<int> idx(cluster.size());
    for (size_t k = 0; k < cluster.size(); ++k) {
      sub.push(ax_[cluster[k]], ay_[cluster[k]], aw_[cluster[k]]);
      idx[k] = int(k);
    }
    return fitLine(sub, idx);
  }

  /// Least-squares refit, then re-collect the points within the inlier distance of the refined
  /// line over the cluster's span (the RANSAC line may have clipped a slightly tilted wall).
  std::vector<int> refineCluster(const std::vector<int>& cluster) const {
    const Line l = fitActive(cluster);
    double tmin = HUGE_VAL, tmax = -HUGE_VAL;
    for (int i : cluster) {
      const double t = (ax_[i] - l.point.x()) * l.dir.x() + (ay_[i] - l.point.y()) * l.dir.y();
      tmin = std::min(tmin, t);
      tmax = std::max(tmax, t);
    }
    std::vector<int> out;
    const double nx = -l.dir.y(), ny = l.dir.x();
    for (size_t i = 0; i < ax_.size(); ++i) {
      const double dx = ax_[i] - l.point.x(), dy = ay_[i] - l.point.y();
      const double t = dx * l.dir.x() + dy * l.dir.y();
      if (t < tmin || t > tmax) continue;
      if (std::abs(dx * nx + dy * ny) < p_.distance_threshold) out.push_back(int(i));
    }
    return out.size() >= cluster.size() ? out : cluster;
  }

  /// Endpoints: the extreme signed projections of the cluster on the fitted direction.
  LineSegment2 segmentOf(const std::vector<int>& cluster) const {
    const Line l = fitActive(cluster);
    double tmin = HUGE_VAL, tmax = -HUGE_VAL, w = 0.0;
    for (int i : cluster) {
      const double t = (ax_[i] - l.point.x()) * l.dir.x() + (ay_[i] - l.point.y()) * l.dir.y();
      tmin = std::min(tmin, t);
      tmax = std::max(tmax, t);
      w += aw_[i];
    }
    return {l.point + tmin * l.dir, l.point + tmax * l.dir, unsigned(std::lround(w))};
  }

  void remove(const std::vector<int>& cluster) {
    for (int i : cluster) active_[aid_[i]] = 0;
  }

  const WeightedPoints& pts_;
  const LineSegmentExtractorParams& p_;
  std::mt19937 rng_;
  std::vector<char> active_;
  static constexpr size_t kScoreSubset = 1024;
  std::vector<float> ax_, ay_, aw_, sx_, sy_;
  std::vector<int32_t> sw_;
  std::vector<int> aid_, cell_begin_, cell_end_, sorted_id_;
  std::vector<uint64_t> sorted_key_;
};

}  // namespace

std::vector<LineSegment2> LineSegmentExtractor::extract(const std::vector<Eigen::Vector2d>& points,
                                                        LineSegmentStats* stats_out) const {
  const auto t0 = Clock::now();
  LineSegmentStats stats;
  stats.input_points = points.size();
  const WeightedPoints merged = mergeOnGrid(points, params_.merge_resolution);
  stats.merged_points = merged.size();
  std::vector<LineSegment2> segments;
  if (merged.size() >= 2) segments = RansacLines(merged, params_).run(stats);
  stats.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (stats_out) *stats_out = stats;
  return segments;
}

std::vector<LineSegment2> LineSegmentExtractor::extract(const PointCloud& cloud,
                                                        LineSegmentStats* stats) const {
  std::vector<Eigen::Vector2d> pts;
  pts.reserve(cloud.size());
  for (const auto& p : cloud) pts.emplace_back(p.x, p.y);
  return extract(pts, stats);
}

}  // namespace osm_graph_slam
