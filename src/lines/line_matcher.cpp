#include "osm_graph_slam/lines/line_matcher.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <unordered_set>

namespace osm_graph_slam {

const char* toString(MatchFeature f) {
  switch (f) {
    case MatchFeature::kEdge:
      return "edge";
    case MatchFeature::kLine:
      return "line";
    default:
      return "none";
  }
}

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDeg = M_PI / 180.0;
constexpr double kNegInf = -std::numeric_limits<double>::infinity();

/// Finite, non-degenerate segments only (bad input never reaches the search).
std::vector<LineSegment2> sanitize(const std::vector<LineSegment2>& in) {
  std::vector<LineSegment2> out;
  out.reserve(in.size());
  for (const auto& s : in)
    if (s.start.allFinite() && s.end.allFinite() && s.length() > 1e-6 &&
        s.start.cwiseAbs().maxCoeff() < 1e7 && s.end.cwiseAbs().maxCoeff() < 1e7)
      out.push_back(s);
  return out;
}

/// Target segments with precomputed frames, and a uniform grid listing, per cell, the segments
/// within the correspondence radius of the cell (so a query is one cell lookup per endpoint).
class TargetIndex {
 public:
  struct Seg {
    Eigen::Vector2d a, u, n;
    double len;
  };

  TargetIndex(const std::vector<LineSegment2>& target, double radius, double cell, bool brute)
      : brute_(brute), stamp_(target.size(), 0) {
    for (const auto& s : target) {
      const Eigen::Vector2d u = s.direction();
      segs_.push_back({s.start, u, Eigen::Vector2d(-u.y(), u.x()), s.length()});
    }
    if (brute_ || target.empty()) return;
    Eigen::Vector2d lo(HUGE_VAL, HUGE_VAL), hi(-HUGE_VAL, -HUGE_VAL);
    for (const auto& s : target) {
      lo = lo.cwiseMin(s.start).cwiseMin(s.end);
      hi = hi.cwiseMax(s.start).cwiseMax(s.end);
    }
    origin_ = lo - Eigen::Vector2d::Constant(radius + 1e-6);
    const Eigen::Vector2d extent = hi - lo + Eigen::Vector2d::Constant(2 * radius + 2e-6);
    cell_ = std::max(cell, std::sqrt(extent.x() * extent.y() / 4e5));  // at most ~400k cells
    nx_ = std::max(1, int(std::ceil(extent.x() / cell_)));
    ny_ = std::max(1, int(std::ceil(extent.y() / cell_)));
    cells_.assign(size_t(nx_) * ny_, {});
    const double reach = radius + cell_ * M_SQRT1_2;  // cell centre to any point of the cell
    for (size_t k = 0; k < target.size(); ++k) {
      const auto& s = target[k];
      const Eigen::Vector2d smin = s.start.cwiseMin(s.end) - Eigen::Vector2d::Constant(radius);
      const Eigen::Vector2d smax = s.start.cwiseMax(s.end) + Eigen::Vector2d::Constant(radius);
      const int x0 = cellX(smin.x()), x1 = cellX(smax.x()), y0 = cellY(smin.y()),
                y1 = cellY(smax.y());
      for (int x = x0; x <= x1; ++x)
        for (int y = y0; y <= y1; ++y) {
          const Eigen::Vector2d c = origin_ + Eigen::Vector2d(x + 0.5, y + 0.5) * cell_;
          if (pointSegmentDistance(c, s) <= reach) cells_[size_t(y) * nx_ + x].push_back(int(k));
        }
    }
  }

  const std::vector<Seg>& segs() const { return segs_; }
  size_t size() const { return segs_.size(); }

  /// Calls f(k) once for every target segment that may lie within the radius of p or q.
  template <class F>
  void forCandidates(const Eigen::Vector2d& p, const Eigen::Vector2d& q, F&& f) const {
    if (brute_) {
      for (size_t k = 0; k < segs_.size(); ++k) f(int(k));
      return;
    }
    ++cur_;
    for (const Eigen::Vector2d* e : {&p, &q}) {
      const int x = int(std::floor((e->x() - origin_.x()) / cell_));
      const int y = int(std::floor((e->y() - origin_.y()) / cell_));
      if (x < 0 || y < 0 || x >= nx_ || y >= ny_) continue;
      for (int k : cells_[size_t(y) * nx_ + x]) {
        if (stamp_[k] == cur_) continue;
        stamp_[k] = cur_;
        f(k);
      }
    }
  }

 private:
  int cellX(double v) const {
    return std::clamp(int(std::floor((v - origin_.x()) / cell_)), 0, nx_ - 1);
  }
  int cellY(double v) const {
    return std::clamp(int(std::floor((v - origin_.y()) / cell_)), 0, ny_ - 1);
  }

  bool brute_;
  std::vector<Seg> segs_;
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();
  double cell_ = 1.0;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<int>> cells_;
  mutable std::vector<uint32_t> stamp_;
  mutable uint32_t cur_ = 0;
};

struct Score {
  double fitness = kNegInf, avg_distance = 0, coverage = 0, translation = 0;
  int matched = 0;
};

struct Correspondence {
  int source = -1, target = -1;
  double distance = 0.0;
};

struct Hypothesis {
  Pose2 T;
  double translation;
  MatchFeature feature;
};

/// Fitness evaluation, the k-nearest search of the refinement and the least-squares polish, all
/// on one source/target pair.
class Search {
 public:
  Search(const std::vector<LineSegment2>& source, const std::vector<LineSegment2>& target,
         const Pose2& guess, MatchMode mode, const LineMatcherParams& p)
      : p_(p),
        mode_(mode),
        guess_(guess),
        index_(target, p.max_correspondence_distance, p.grid_cell, p.brute_force),
        min_cos_(std::cos(p.max_correspondence_angle_deg * kDeg)) {
    // Longest first: the coverage bound of the early exit tightens fastest.
    std::vector<LineSegment2> sorted = source;
    std::sort(sorted.begin(), sorted.end(),
              [](const LineSegment2& a, const LineSegment2& b) { return a.length() > b.length(); });
    source_ = sorted;
    total_length_ = 0.0;
    for (const auto& s : source_) total_length_ += s.length();
    suffix_length_.assign(source_.size() + 1, 0.0);
    for (size_t i = source_.size(); i-- > 0;)
      suffix_length_[i] = suffix_length_[i + 1] + source_[i].length();
  }

  const std::vector<LineSegment2>& source() const { return source_; }
  const TargetIndex& index() const { return index_; }

  double translationOf(const Pose2& T) const { return std::hypot(T.x - guess_.x, T.y - guess_.y); }

  /// Distance and coverage of a transformed source segment to target k (mode's metric).
  CoverageDistance distanceTo(const Eigen::Vector2d& a, const Eigen::Vector2d& b, int k) const {
    const auto& t = index_.segs()[k];
    if (mode_ != MatchMode::kGlobal) {
      const LineSegment2 ts(t.a, t.a + t.len * t.u);
      return segmentDistanceWithCoverage(LineSegment2(a, b), ts);
    }
    auto endpointDistance = [&](const Eigen::Vector2d& p, double tau) {
      if (tau >= 0.0 && tau <= t.len) return std::abs((p - t.a).dot(t.n));
      return (p - (tau < 0.0 ? t.a : Eigen::Vector2d(t.a + t.len * t.u))).norm();
    };
    const double ta = (a - t.a).dot(t.u), tb = (b - t.a).dot(t.u);
    CoverageDistance out;
    out.distance = 0.5 * (endpointDistance(a, ta) + endpointDistance(b, tb));
    out.coverage =
        std::max(0.0, std::min(t.len, std::max(ta, tb)) - std::max(0.0, std::min(ta, tb)));
    return out;
  }

  /// Best target of one transformed source segment within the correspondence radius and angle.
  Correspondence nearest(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                         double* coverage) const {
    const Eigen::Vector2d u = (b - a).normalized();
    Correspondence best;
    best.distance = HUGE_VAL;
    double best_cov = 0.0;
    index_.forCandidates(a, b, [&](int k) {
      if (std::abs(u.dot(index_.segs()[k].u)) < min_cos_) return;
      const CoverageDistance d = distanceTo(a, b, k);
      if (d.distance < best.distance || (d.distance == best.distance && d.coverage > best_cov)) {
        best.distance = d.distance;
        best.target = k;
        best_cov = d.coverage;
      }
    });
    if (coverage) *coverage = best_cov;
    return best;
  }

  /// Eq. 3.1-3.4. Returns fitness -inf as soon as the fitness provably cannot reach `bound`.
  Score evaluate(const Pose2& T, double bound = kNegInf) const {
    Score s;
    s.translation = translationOf(T);
    const double n = double(source_.size());
    const double trans_w = p_.weight_translation *
                           std::min(p_.max_translation_fitness, s.translation) /
                           p_.max_translation_fitness * 100.0;
    const double dmax = p_.max_correspondence_distance;
    double dist_sum = 0.0, cov_sum = 0.0;
    for (size_t i = 0; i < source_.size(); ++i) {
      const Eigen::Vector2d a = T.transform(source_[i].start), b = T.transform(source_[i].end);
      double cov = 0.0;
      const Correspondence c = nearest(a, b, &cov);
      if (c.target >= 0 && c.distance < dmax) {
        dist_sum += c.distance;
        cov_sum += cov;
        if (c.distance < p_.matched_distance) ++s.matched;
      } else {
        dist_sum += dmax;
      }
      if (bound > kNegInf) {
        const double upper = fitnessOf(dist_sum / n, cov_sum + suffix_length_[i + 1]) - trans_w;
        if (upper < bound) return Score{};
      }
    }
    s.avg_distance = dist_sum / n;
    s.coverage = cov_sum;
    s.fitness = fitnessOf(s.avg_distance, s.coverage) - trans_w;
    return s;
  }

  std::vector<Correspondence> correspondences(const Pose2& T, double max_distance) const {
    std::vector<Correspondence> out;
    for (size_t i = 0; i < source_.size(); ++i) {
      Correspondence c =
          nearest(T.transform(source_[i].start), T.transform(source_[i].end), nullptr);
      if (c.target < 0 || c.distance > max_distance) continue;
      c.source = int(i);
      out.push_back(c);
    }
    return out;
  }

  /// Up to k nearest targets of transformed source segment i (refinement candidates).
  std::vector<int> kNearest(const Pose2& T, size_t i, int k) const {
    const Eigen::Vector2d a = T.transform(source_[i].start), b = T.transform(source_[i].end);
    std::vector<std::pair<double, int>> cand;
    index_.forCandidates(a, b, [&](int t) { cand.emplace_back(distanceTo(a, b, t).distance, t); });
    std::sort(cand.begin(), cand.end());
    std::vector<int> out;
    for (size_t j = 0; j < cand.size() && int(out.size()) < k; ++j)
      if (cand[j].first < p_.max_correspondence_distance) out.push_back(cand[j].second);
    return out;
  }

  /// Gauss-Newton on the distances of the source endpoints to their matched target lines
  /// (length-weighted, damped so that a direction no wall constrains stays where it is).
  Pose2 polish(Pose2 T) const {
    for (int it = 0; it < p_.polish_iterations; ++it) {
      const auto corr = correspondences(T, 2.0 * p_.matched_distance);
      if (corr.empty()) break;
      Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      for (const auto& c : corr) {
        const auto& t = index_.segs()[c.target];
        const LineSegment2& s = source_[c.source];
        const double w = s.length();
        for (const Eigen::Vector2d& p : {s.start, s.end}) {
          const Eigen::Vector2d rp = T.rotation() * p;
          const double r = t.n.dot(rp + T.translation() - t.a);
          const Eigen::Vector3d J(t.n.x(), t.n.y(), t.n.dot(Eigen::Vector2d(-rp.y(), rp.x())));
          H += w * J * J.transpose();
          g += w * J * r;
        }
      }
      H += 1e-6 * (H.trace() + 1e-9) * Eigen::Matrix3d::Identity();
      const Eigen::Vector3d d = -H.ldlt().solve(g);
      if (!d.allFinite()) break;
      T = Pose2(T.x + d.x(), T.y + d.y(), wrapAngle(T.theta + d.z()));
      if (d.head<2>().norm() < 1e-5 && std::abs(d.z()) < 1e-6) break;
    }
    return T;
  }

 private:
  double fitnessOf(double avg_distance, double coverage) const {
    const double dist_w = p_.weight_distance * std::min(p_.max_avg_distance, avg_distance) /
                          p_.max_avg_distance * 100.0;
    const double cov_w =
        total_length_ > 0.0 ? p_.weight_coverage * coverage / total_length_ * 100.0 : 0.0;
    return -dist_w + cov_w;
  }

  const LineMatcherParams& p_;
  MatchMode mode_;
  Pose2 guess_;
  std::vector<LineSegment2> source_;
  TargetIndex index_;
  double min_cos_;
  double total_length_ = 0.0;
  std::vector<double> suffix_length_;
};

/// Rejects duplicate hypotheses (2 cm, 0.1 deg) produced by different feature pairs.
class HypothesisSet {
 public:
  bool insert(const Pose2& T) {
    const int64_t kx = std::llround(T.x / 0.02), ky = std::llround(T.y / 0.02),
                  kt = std::llround(T.theta / (0.1 * kDeg));
    const uint64_t key =
        (uint64_t(kx) * 73856093ULL) ^ (uint64_t(ky) * 19349663ULL) ^ (uint64_t(kt) * 83492791ULL);
    return seen_.insert(key).second;
  }

 private:
  std::unordered_set<uint64_t> seen_;
};

struct Bounds {
  double max_translation;
  double max_rotation;  // rad; >= pi means unbounded
};

bool withinBounds(const Pose2& T, const Pose2& guess, const Bounds& b) {
  return std::hypot(T.x - guess.x, T.y - guess.y) <= b.max_translation &&
         (b.max_rotation >= M_PI || std::abs(wrapAngle(T.theta - guess.theta)) <= b.max_rotation);
}

/// Edge-pair hypotheses (§3.3.2). Target edges are sorted so that, for each source edge, only
/// the target corners that the bounds allow are visited (a window by x, or a band of radius when
/// the rotation is unbounded); the opening angle and arm-length signatures prune the rest.
std::vector<Hypothesis> edgeHypotheses(const std::vector<LineEdge>& es,
                                       const std::vector<LineEdge>& et, const Pose2& guess,
                                       MatchMode mode, const Bounds& b, const LineMatcherParams& p,
                                       LineMatchStats& stats) {
  std::vector<Hypothesis> out;
  const double tol = p.edge_angle_tolerance_deg * kDeg;
  const bool unbounded = b.max_rotation >= M_PI;
  const Eigen::Vector2d g0 = guess.translation();

  auto tryPair = [&](const LineEdge& s, const LineEdge& t) {
    std::vector<double> rotations;
    if (mode == MatchMode::kOverlap) {
      // Walls flush in any arrangement: align the lines modulo pi, either assignment.
      for (int swap = 0; swap < 2; ++swap) {
        const double ta = swap ? t.ray2 : t.ray1, tb = swap ? t.ray1 : t.ray2;
        for (int k = 0; k < 2; ++k) {
          const double phi = wrapAngle(ta - s.ray1 + k * M_PI);
          const double other = wrapAngle(tb - s.ray2 - phi);
          if (std::abs(std::sin(other)) <= std::sin(tol)) rotations.push_back(phi);
        }
      }
    } else {
      if (std::abs(s.opening - t.opening) > tol) return;
      const bool lidar_source = mode == MatchMode::kGlobal;
      const double s1 = lidar_source ? s.arm1 : t.arm1, l1 = lidar_source ? t.arm1 : s.arm1;
      const double s2 = lidar_source ? s.arm2 : t.arm2, l2 = lidar_source ? t.arm2 : s.arm2;
      if (!p.brute_force && (s1 > l1 + p.edge_length_slack || s2 > l2 + p.edge_length_slack))
        return;
      const double d1 = wrapAngle(t.ray1 - s.ray1);
      rotations.push_back(wrapAngle(d1 + 0.5 * wrapAngle(wrapAngle(t.ray2 - s.ray2) - d1)));
    }
    for (double theta : rotations) {
      Pose2 T(0, 0, theta);
      const Eigen::Vector2d tr = t.corner - T.rotation() * s.corner;
      T.x = tr.x();
      T.y = tr.y();
      if (!withinBounds(T, guess, b)) continue;
      ++stats.edge_pairs_in_bounds;
      out.push_back({T, (tr - g0).norm(), MatchFeature::kEdge});
    }
  };

  if (p.brute_force) {
    for (const auto& s : es)
      for (const auto& t : et) tryPair(s, t);
    return out;
  }
  // Key of a target edge: its corner's x (bounded rotation) or distance to the guess origin.
  std::vector<std::pair<double, int>> keyed(et.size());
  for (size_t j = 0; j < et.size(); ++j)
    keyed[j] = {unbounded ? (et[j].corner - g0).norm() : et[j].corner.x(), int(j)};
  std::sort(keyed.begin(), keyed.end());
  const double chord = unbounded ? 2.0 : 2.0 * std::sin(0.5 * b.max_rotation);
  for (const auto& s : es) {
    const Eigen::Vector2d gc = guess.transform(s.corner);
    const double radius = b.max_translation + chord * s.corner.norm();
    const double key = unbounded ? s.corner.norm() : gc.x();
    const double lo = unbounded ? key - b.max_translation : key - radius;
    const double hi = unbounded ? key + b.max_translation : key + radius;
    auto it = std::lower_bound(keyed.begin(), keyed.end(), std::make_pair(lo, -1));
    for (; it != keyed.end() && it->first <= hi; ++it) {
      const LineEdge& t = et[it->second];
      if (!unbounded && (t.corner - gc).norm() > radius) continue;
      tryPair(s, t);
    }
  }
  return out;
}

/// Line-pair transforms (§3.3.3) around T0: rotate the source segment parallel to the target
/// (smallest angle, about its midpoint), then move it onto the target line along the normal.
Pose2 linePairTransform(const Pose2& T0, const LineSegment2& source, const TargetIndex::Seg& t) {
  const LineSegment2 s = source.transformed(T0);
  const Eigen::Vector2d u = s.direction();
  double dtheta = wrapAngle(std::atan2(t.u.y(), t.u.x()) - std::atan2(u.y(), u.x()));
  if (dtheta > M_PI / 2) dtheta -= M_PI;
  if (dtheta < -M_PI / 2) dtheta += M_PI;
  const Eigen::Vector2d m = s.midpoint();
  const Pose2 rot(0, 0, dtheta);
  const Eigen::Vector2d rot_t = m - rot.rotation() * m;
  const Pose2 about_mid(rot_t.x(), rot_t.y(), dtheta);
  const Eigen::Vector2d shift = t.n * t.n.dot(t.a - m);
  return Pose2(shift.x(), shift.y(), 0.0) * about_mid * T0;
}

/// Line-pair hypotheses from the guess (local matching): each wall made collinear with each
/// parallel keyframe segment within local_line_seed_distance. Without them a building seen through
/// one facade (no corner) is matched only if its prior is within the correspondence radius.
void lineSeedHypotheses(const Search& search, const Pose2& guess, const Bounds& bounds,
                        const LineMatcherParams& p, std::vector<Hypothesis>& hyps) {
  if (!(p.local_line_seed_distance > 0.0)) return;
  const double min_cos = std::cos(p.max_correspondence_angle_deg * kDeg);
  const auto& targets = search.index().segs();
  for (const LineSegment2& wall : search.source()) {
    const LineSegment2 placed = wall.transformed(guess);
    const Eigen::Vector2d u = placed.direction();
    for (const auto& t : targets) {
      if (std::abs(u.dot(t.u)) < min_cos) continue;
      const LineSegment2 ts(t.a, t.a + t.len * t.u);
      if (segmentDistanceWithCoverage(placed, ts).distance > p.local_line_seed_distance) continue;
      const Pose2 T = linePairTransform(guess, wall, t);
      if (withinBounds(T, guess, bounds))
        hyps.push_back({T, search.translationOf(T), MatchFeature::kLine});
    }
  }
}

void fillResult(LineMatchResult& r, const Search& search, const Pose2& T, MatchFeature feature,
                const LineMatcherParams& p) {
  const Score s = search.evaluate(T);
  r.transform = T;
  r.fitness = s.fitness;
  r.avg_distance = s.avg_distance;
  r.coverage = s.coverage;
  r.translation = s.translation;
  r.matched_segments = s.matched;
  r.feature = feature;

  // Which directions do the matched walls constrain? Structure tensor of their normals.
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double matched_length = 0.0;
  for (const auto& c : search.correspondences(T, p.matched_distance)) {
    const Eigen::Vector2d& n = search.index().segs()[c.target].n;
    const LineSegment2& src = search.source()[c.source];
    S += src.length() * n * n.transpose();
    centre += src.length() * T.transform(src.midpoint());
    matched_length += src.length();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(S);
  const double ratio = es.eigenvalues()(1) > 0 ? es.eigenvalues()(0) / es.eigenvalues()(1) : 0.0;
  const double lim = std::sin(p.two_dof_max_angle_deg * kDeg);
  r.two_dof = r.matched_segments > 0 && ratio < 0.5 * lim * lim;
  r.constrained_normal = es.eigenvectors().col(1);

  const bool edge = feature == MatchFeature::kEdge;
  const double xy = edge ? p.edge_information_xy : p.line_information_xy;
  const double th = edge ? p.edge_information_theta : p.line_information_theta;
  const double top = 100.0 * p.weight_coverage;  // fitness of a perfect, complete match
  const double scale =
      top > p.min_fitness
          ? std::clamp((s.fitness - p.min_fitness) / (top - p.min_fitness), 0.0, 1.0)
          : 1.0;
  r.information.setZero();
  Eigen::Matrix2d txy = xy * Eigen::Matrix2d::Identity();
  if (r.two_dof) {
    const Eigen::Vector2d& n = r.constrained_normal;
    const Eigen::Matrix2d nn = n * n.transpose();
    txy = xy * (nn + p.two_dof_along_scale * (Eigen::Matrix2d::Identity() - nn));
  }
  r.information.topLeftCorner<2, 2>() = scale * txy;
  r.information(2, 2) = scale * th;
  r.matched_centre =
      matched_length > 0.0 ? Eigen::Vector2d(centre / matched_length) : T.translation();
  r.success = s.fitness >= p.min_fitness && s.matched >= p.min_matched_segments;
  if (!r.success) r.message = "fitness or matched segments below the thresholds";
}

/// First pose: the best hypothesis at a clearly different heading must score clearly lower,
/// otherwise the heading is a guess between look-alike corners (e.g. a symmetric square).
void refuseAmbiguousHeading(LineMatchResult& r, const Search& search,
                            const std::vector<Hypothesis>& hyps, const LineMatcherParams& p) {
  double runner_up = kNegInf;
  for (const auto& h : hyps) {
    if (std::abs(wrapAngle(h.T.theta - r.transform.theta)) <= p.initial_distinct_heading_deg * kDeg)
      continue;
    runner_up = std::max(runner_up, search.evaluate(h.T, runner_up).fitness);
  }
  r.runner_up_fitness = runner_up;
  if (r.success && p.initial_ambiguity_margin > 0.0 &&
      r.fitness - runner_up < p.initial_ambiguity_margin) {
    r.success = false;
    r.message = "ambiguous heading: a hypothesis " +
                std::to_string(p.initial_distinct_heading_deg) + "+ deg away scores " +
                std::to_string(runner_up) + " against " + std::to_string(r.fitness);
  }
}

}  // namespace

LineMatchResult LineMatcher::matchGlobal(const std::vector<LineSegment2>& keyframe_segments,
                                         const std::vector<LineSegment2>& building_segments,
                                         const Pose2& guess, bool rotation_unbounded) const {
  return match(keyframe_segments, building_segments, guess, MatchMode::kGlobal, rotation_unbounded);
}

LineMatchResult LineMatcher::matchLocal(const std::vector<LineSegment2>& building_segments,
                                        const std::vector<LineSegment2>& keyframe_segments,
                                        const Pose2& guess) const {
  return match(building_segments, keyframe_segments, guess, MatchMode::kLocal);
}

LineMatchResult LineMatcher::match(const std::vector<LineSegment2>& source_in,
                                   const std::vector<LineSegment2>& target_in, const Pose2& guess,
                                   MatchMode mode, bool rotation_unbounded) const {
  const auto t0 = Clock::now();
  LineMatchResult result;
  result.transform = guess;
  const std::vector<LineSegment2> source = sanitize(source_in), target = sanitize(target_in);
  result.stats.source_segments = source.size();
  result.stats.target_segments = target.size();
  if (source.empty() || target.empty() || !std::isfinite(guess.x) || !std::isfinite(guess.y) ||
      !std::isfinite(guess.theta)) {
    result.message = "no usable source or target segments (or a non-finite guess)";
    return result;
  }
  const LineMatcherParams& p = params_;
  const bool first_pose = mode == MatchMode::kGlobal && rotation_unbounded;
  const Bounds bounds{mode == MatchMode::kOverlap ? p.overlap_max_translation
                      : first_pose ? std::max(p.max_translation, p.initial_max_translation)
                                   : p.max_translation,
                      rotation_unbounded            ? M_PI
                      : mode == MatchMode::kOverlap ? p.overlap_max_rotation_deg * kDeg
                                                    : p.max_rotation_deg * kDeg};
  Search search(source, target, guess, mode, p);

  // Source edges in the source frame, target edges in the target frame.
  const EdgeParams ep{p.min_edge_angle_deg, p.edge_endpoint_tolerance, p.max_virtual_edge_distance};
  const auto es = extractEdges(search.source(), ep), et = extractEdges(target, ep);
  result.stats.source_edges = es.size();
  result.stats.target_edges = et.size();
  result.stats.edge_pairs_total = es.size() * et.size();
  std::vector<Hypothesis> hyps = edgeHypotheses(es, et, guess, mode, bounds, p, result.stats);
  hyps.push_back({guess, 0.0, MatchFeature::kLine});  // the guess itself competes
  if (mode == MatchMode::kLocal) lineSeedHypotheses(search, guess, bounds, p, hyps);

  // Edge search: smallest translation first, each evaluation abandoned once it cannot win.
  std::stable_sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) {
    return a.translation < b.translation;
  });
  HypothesisSet seen;
  Hypothesis best = hyps.front();
  double best_fitness = kNegInf;
  for (const auto& h : hyps) {
    if (!p.brute_force && !seen.insert(h.T)) continue;
    ++result.stats.hypotheses_evaluated;
    const Score s = search.evaluate(h.T, p.brute_force ? kNegInf : best_fitness);
    if (s.fitness > best_fitness) {
      best_fitness = s.fitness;
      best = h;
    }
  }

  // Line-pair refinement from the best transform against the k nearest target segments.
  for (int round = 0; round < p.refine_rounds; ++round) {
    const Pose2 base = best.T;
    bool improved = false;
    for (size_t i = 0; i < search.source().size(); ++i) {
      for (int k : search.kNearest(base, i, p.refine_k_nearest)) {
        const Pose2 T = linePairTransform(base, search.source()[i], search.index().segs()[k]);
        if (!withinBounds(T, guess, bounds) || (!p.brute_force && !seen.insert(T))) continue;
        ++result.stats.line_pairs_evaluated;
        const Score s = search.evaluate(T, p.brute_force ? kNegInf : best_fitness);
        if (s.fitness > best_fitness) {
          best_fitness = s.fitness;
          best = {T, s.translation, MatchFeature::kLine};
          improved = true;
        }
      }
    }
    if (!improved) break;
  }

  Pose2 final_T = best.T;
  if (p.least_squares_polish) {
    const Pose2 polished = search.polish(best.T);
    if (withinBounds(polished, guess, bounds) &&
        search.evaluate(polished).avg_distance <= search.evaluate(best.T).avg_distance + 1e-4)
      final_T = polished;
  }
  fillResult(result, search, final_T, best.feature, p);
  if (first_pose) refuseAmbiguousHeading(result, search, hyps, p);
  result.stats.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  return result;
}

namespace {

/// The guess shifted by the shortest translation (5 cm steps up to max_translation, 36
/// directions) after which `overlaps` is false; nothing if none within the bound.
template <typename Overlaps>
std::optional<Pose2> shortestSeparatingShift(const Pose2& guess, double max_translation,
                                             const Overlaps& overlaps) {
  constexpr double kStep = 0.05;
  constexpr int kDirections = 36;
  for (double d = kStep; d <= max_translation + 1e-9; d += kStep)
    for (int k = 0; k < kDirections; ++k) {
      const double a = 2.0 * M_PI * k / kDirections;
      const Pose2 T(guess.x + d * std::cos(a), guess.y + d * std::sin(a), guess.theta);
      if (!overlaps(T)) return T;
    }
  return std::nullopt;
}

}  // namespace

LineMatchResult LineMatcher::removeOverlap(const Polygon2& building_a, const Pose2& guess,
                                           const Polygon2& building_b) const {
  const auto t0 = Clock::now();
  const LineMatcherParams& p = params_;
  LineMatchResult result;
  result.transform = guess;
  const auto source = sanitize(polygonSegments(building_a));
  const auto target = sanitize(polygonSegments(building_b));
  result.stats.source_segments = source.size();
  result.stats.target_segments = target.size();
  if (source.size() < 3 || target.size() < 3) {
    result.message = "an outline has fewer than three walls";
    return result;
  }
  auto overlaps = [&](const Pose2& T) {
    return polygonOverlapArea(transformPolygon(building_a, T), building_b) >= p.min_overlap_area;
  };
  Search search(source, target, guess, MatchMode::kOverlap, p);
  if (!overlaps(guess)) {
    fillResult(result, search, guess, MatchFeature::kNone, p);
    result.success = true;
    result.message = "outlines do not overlap";
    return result;
  }
  const Bounds bounds{p.overlap_max_translation, p.overlap_max_rotation_deg * kDeg};
  const EdgeParams ep{p.min_edge_angle_deg, p.edge_endpoint_tolerance, p.max_virtual_edge_distance};
  const auto es = extractEdges(search.source(), ep), et = extractEdges(target, ep);
  result.stats.source_edges = es.size();
  result.stats.target_edges = et.size();
  result.stats.edge_pairs_total = es.size() * et.size();
  std::vector<Hypothesis> hyps =
      edgeHypotheses(es, et, guess, MatchMode::kOverlap, bounds, p, result.stats);
  // Every wall of A flush with every wall of B (line pairs from the guess).
  for (const auto& s : search.source())
    for (const auto& t : search.index().segs()) {
      const Pose2 T = linePairTransform(guess, s, t);
      ++result.stats.line_pairs_evaluated;
      if (withinBounds(T, guess, bounds))
        hyps.push_back({T, search.translationOf(T), MatchFeature::kLine});
    }
  std::stable_sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) {
    return a.translation < b.translation;
  });
  HypothesisSet seen;
  for (const auto& h : hyps) {
    if (!seen.insert(h.T)) continue;
    ++result.stats.hypotheses_evaluated;
    if (overlaps(h.T)) continue;
    fillResult(result, search, h.T, h.feature, p);
    result.success = true;  // separated: the fitness only describes how well the walls meet
    result.message.clear();
    result.two_dof = false;
    result.stats.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    return result;
  }
  // A corner poking into a concave neighbour may have no wall parallel to one of the
  // neighbour's within the bounds, so no corner or flush hypothesis separates them (real drive
  // 0005: 118192368 into 93311299, 1.07 m^2 left). Then the shortest pure shift that does.
  if (const auto shift = shortestSeparatingShift(guess, p.overlap_max_translation, overlaps)) {
    fillResult(result, search, *shift, MatchFeature::kNone, p);
    result.success = true;
    result.message = "separated by the shortest shift";
    result.two_dof = false;
    result.stats.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    return result;
  }
  result.message = "no edge, line or shift within the bounds removes the overlap";
  result.stats.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  return result;
}

Eigen::Matrix3d scaledInformation(const Eigen::Matrix3d& matcher_info, double std_xy,
                                  double std_theta, const LineMatcherParams& m) {
  Eigen::Matrix3d info = matcher_info;
  const double sxy = 1.0 / (std_xy * std_xy * m.edge_information_xy);
  const double sth = 1.0 / (std_theta * std_theta * m.edge_information_theta);
  info.topLeftCorner<2, 2>() *= sxy;
  info(2, 2) *= sth;
  info.topRightCorner<2, 1>() *= std::sqrt(sxy * sth);
  info.bottomLeftCorner<1, 2>() *= std::sqrt(sxy * sth);
  return info;
}

}  // namespace osm_graph_slam
