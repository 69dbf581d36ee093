#include "osm_graph_slam/landmarks/hierarchy_matching.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <unordered_map>

#include "osm_graph_slam/common/cell_key.h"

namespace osm_graph_slam {

namespace {

/// Hash grid over 2D points for radius queries.
class PointGrid {
 public:
  PointGrid(const std::vector<Eigen::Vector2d>& points, double cell)
      : points_(points), cell_(cell) {
    for (size_t i = 0; i < points.size(); ++i) cells_[key(cellOf(points[i]))].push_back(int(i));
  }
  /// Nearest point within radius (radius <= cell), -1 if none.
  int nearest(const Eigen::Vector2d& p, double radius, double* dist = nullptr) const {
    const Eigen::Vector2i c = cellOf(p);
    int best = -1;
    double best_d2 = radius * radius;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find(key(c + Eigen::Vector2i(dx, dy)));
        if (it == cells_.end()) continue;
        for (int i : it->second) {
          const double d2 = (points_[i] - p).squaredNorm();
          if (d2 <= best_d2) {
            best_d2 = d2;
            best = i;
          }
        }
      }
    if (dist) *dist = std::sqrt(best_d2);
    return best;
  }

 private:
  Eigen::Vector2i cellOf(const Eigen::Vector2d& p) const {
    return Eigen::Vector2i(int(std::floor(p.x() / cell_)), int(std::floor(p.y() / cell_)));
  }
  static int64_t key(const Eigen::Vector2i& c) { return packCellKey(c.x(), c.y()); }
  const std::vector<Eigen::Vector2d>& points_;
  double cell_;
  std::unordered_map<int64_t, std::vector<int>> cells_;
};

double sortedSideDistance(const HierarchyTriangle& a, const HierarchyTriangle& b) {
  double s = 0.0;
  for (int i = 0; i < 3; ++i)
    s += (a.sorted_sides[i] - b.sorted_sides[i]) * (a.sorted_sides[i] - b.sorted_sides[i]);
  return std::sqrt(s);
}

/// Cyclic rotation r (query side i <-> candidate side (i + r) % 3) with the closest side lengths;
/// both triangles are counter-clockwise, so no reflection is considered.
int bestRotation(const HierarchyTriangle& q, const HierarchyTriangle& c) {
  int best = 0;
  double best_cost = 1e300;
  for (int r = 0; r < 3; ++r) {
    double cost = 0.0;
    for (int i = 0; i < 3; ++i) cost += std::pow(q.side[i] - c.side[(i + r) % 3], 2);
    if (cost < best_cost) {
      best_cost = cost;
      best = r;
    }
  }
  return best;
}

/// Matched triangle pairs of one polygon pair (greedy by distance), empty below eta.
std::vector<std::pair<int, int>> matchPolygonTriangles(const UrquhartPolygon& pq,
                                                       const UrquhartPolygon& pc,
                                                       const GeometricHierarchy& q,
                                                       const GeometricHierarchy& c,
                                                       const HierarchyMatchParams& params) {
  struct Cand {
    double d;
    int a, b;
  };
  std::vector<Cand> cands;
  for (int a : pq.triangles)
    for (int b : pc.triangles) {
      const double d = sortedSideDistance(q.triangles[a], c.triangles[b]);
      if (d < params.triangle_max_side_difference) cands.push_back({d, a, b});
    }
  std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) { return x.d < y.d; });
  std::vector<std::pair<int, int>> out;
  std::vector<int> used_a, used_b;
  for (const Cand& k : cands) {
    if (std::count(used_a.begin(), used_a.end(), k.a) ||
        std::count(used_b.begin(), used_b.end(), k.b))
      continue;
    used_a.push_back(k.a);
    used_b.push_back(k.b);
    out.push_back({k.a, k.b});
  }
  const double ratio =
      double(out.size()) / double(std::max(pq.triangles.size(), pc.triangles.size()));
  if (ratio < params.min_triangle_match_ratio) out.clear();
  return out;
}

struct Scored {
  Eigen::Isometry2d transform = Eigen::Isometry2d::Identity();
  std::vector<std::pair<int, int>> associations;
  int overlap = 0;
  double sum_d2 = 0.0;
};

/// One-to-one nearest-neighbour associations of the transformed query landmarks.
Scored associate(const Eigen::Isometry2d& T, const std::vector<Eigen::Vector2d>& query,
                 const std::vector<Eigen::Vector2d>& cand, const PointGrid& fine,
                 const PointGrid& coarse, const HierarchyMatchParams& params) {
  Scored s;
  s.transform = T;
  std::vector<double> best_d(cand.size(), 1e300);
  std::vector<int> best_q(cand.size(), -1);
  for (size_t i = 0; i < query.size(); ++i) {
    const Eigen::Vector2d p = T * query[i];
    if (coarse.nearest(p, params.overlap_radius) < 0) continue;
    ++s.overlap;
    double d = 0.0;
    const int j = fine.nearest(p, params.inlier_distance, &d);
    if (j >= 0 && d < best_d[j]) {
      best_d[j] = d;
      best_q[j] = int(i);
    }
  }
  for (size_t j = 0; j < cand.size(); ++j)
    if (best_q[j] >= 0) {
      s.associations.push_back({best_q[j], int(j)});
      s.sum_d2 += best_d[j] * best_d[j];
    }
  return s;
}

/// Triangle tier: every query triangle against every candidate triangle by sorted sides (a
/// Delaunay triangle whose three landmarks are seen in both frames is a Delaunay triangle of
/// both, whatever else is missed, while the polygons around it change). With 0.2 m landmark
/// noise side lengths differ by ~0.4 m, so the threshold is loose and many pairs are look-alikes;
/// the pairs are ordered by a Hough vote of their transforms (the true pairs agree on one
/// transform, look-alikes scatter), at most triangle_tier_hypotheses, skipping pairs already
/// given by the polygon tier.
std::vector<std::pair<int, int>> matchTrianglesDirectly(
    const GeometricHierarchy& q, const GeometricHierarchy& c, const HierarchyMatchParams& params,
    const std::vector<std::pair<int, int>>& already) {
  struct Cand {
    int a, b;
    int64_t bin[3];
    int votes = 0;
    double d = 0.0;
  };
  std::vector<Cand> cands;
  const double thr = params.triangle_tier_max_side_difference;
  const double bin_t = params.hough_translation_bin, bin_r = params.hough_rotation_bin;
  std::unordered_map<int64_t, int> bins;
  auto binKey = [](int64_t x, int64_t y, int64_t r) {
    return (x & 0x1fffff) | ((y & 0x1fffff) << 21) | ((r & 0x1fffff) << 42);
  };
  for (size_t a = 0; a < q.triangles.size(); ++a) {
    const HierarchyTriangle& ta = q.triangles[a];
    const auto& sa = ta.sorted_sides;
    for (size_t b = 0; b < c.triangles.size(); ++b) {
      const HierarchyTriangle& tb = c.triangles[b];
      const auto& sb = tb.sorted_sides;
      if (std::abs(sa[0] - sb[0]) > thr) continue;
      const double d =
          std::sqrt((sa[0] - sb[0]) * (sa[0] - sb[0]) + (sa[1] - sb[1]) * (sa[1] - sb[1]) +
                    (sa[2] - sb[2]) * (sa[2] - sb[2]));
      if (d >= thr) continue;
      const int r = bestRotation(ta, tb);
      std::vector<Eigen::Vector2d> pa, pb;
      for (int i = 0; i < 3; ++i) {
        pa.push_back(q.points[ta.v[i]]);
        pb.push_back(c.points[tb.v[(i + r) % 3]]);
      }
      const Eigen::Isometry2d T = fitRigid2d(pa, pb);
      const double yaw = std::atan2(T.linear()(1, 0), T.linear()(0, 0));
      Cand k;
      k.a = int(a);
      k.b = int(b);
      k.d = d;
      k.bin[0] = int64_t(std::floor(T.translation().x() / bin_t));
      k.bin[1] = int64_t(std::floor(T.translation().y() / bin_t));
      k.bin[2] = int64_t(std::floor((yaw + M_PI) / bin_r));
      ++bins[binKey(k.bin[0], k.bin[1], k.bin[2])];
      cands.push_back(k);
    }
  }
  const int64_t yaw_bins = int64_t(std::ceil(2.0 * M_PI / bin_r));
  for (Cand& k : cands)  // votes of the 3x3x3 neighbourhood (yaw wraps)
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dr = -1; dr <= 1; ++dr) {
          const auto it = bins.find(binKey(k.bin[0] + dx, k.bin[1] + dy,
                                           ((k.bin[2] + dr) % yaw_bins + yaw_bins) % yaw_bins));
          if (it != bins.end()) k.votes += it->second;
        }
  std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) {
    if (x.votes != y.votes) return x.votes > y.votes;
    if (x.d != y.d) return x.d < y.d;
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });
  std::vector<std::pair<int, int>> out;
  for (const Cand& k : cands) {
    if (int(out.size()) >= params.triangle_tier_hypotheses || k.votes < params.hough_min_votes)
      break;
    const std::pair<int, int> p{k.a, k.b};
    if (std::find(already.begin(), already.end(), p) == already.end()) out.push_back(p);
  }
  return out;
}

}  // namespace

std::vector<LandmarkCorrespondence> matchHierarchies(
    const GeometricHierarchy& query, const GeometricHierarchy& candidate,
    const HierarchyMatchParams& params, const std::vector<PolygonPair>* polygon_pairs,
    std::vector<std::pair<int, int>>* triangle_pairs, int* matched_polygons) {
  std::vector<PolygonPair> all_pairs;
  if (!polygon_pairs) {
    for (size_t a = 0; a < query.polygons.size(); ++a)
      for (size_t b = 0; b < candidate.polygons.size(); ++b) all_pairs.push_back({int(a), int(b)});
    polygon_pairs = &all_pairs;
  }
  const double tau2 =
      params.polygon_max_descriptor_distance * params.polygon_max_descriptor_distance;
  std::map<std::pair<int, int>, int> votes;
  std::map<std::pair<int, int>, bool> triangle_seen;
  int polygons = 0;
  for (const PolygonPair& pp : *polygon_pairs) {
    if (pp.query < 0 || pp.query >= int(query.polygons.size()) || pp.candidate < 0 ||
        pp.candidate >= int(candidate.polygons.size()))
      continue;
    const UrquhartPolygon& pq = query.polygons[pp.query];
    const UrquhartPolygon& pc = candidate.polygons[pp.candidate];
    if (std::abs(int(pq.vertices.size()) - int(pc.vertices.size())) >
        params.polygon_max_vertex_difference)
      continue;
    if ((pq.descriptor - pc.descriptor).squaredNorm() > tau2) continue;
    const auto tris = matchPolygonTriangles(pq, pc, query, candidate, params);
    if (tris.empty()) continue;
    ++polygons;
    for (const auto& [a, b] : tris) {
      if (!triangle_seen.emplace(std::make_pair(a, b), true).second) continue;
      if (triangle_pairs) triangle_pairs->push_back({a, b});
      const HierarchyTriangle& tq = query.triangles[a];
      const HierarchyTriangle& tc = candidate.triangles[b];
      const int r = bestRotation(tq, tc);
      for (int i = 0; i < 3; ++i) ++votes[{tq.v[i], tc.v[(i + r) % 3]}];
    }
  }
  if (matched_polygons) *matched_polygons = polygons;
  std::vector<LandmarkCorrespondence> out;
  for (const auto& [pair, n] : votes) out.push_back({pair.first, pair.second, n});
  return out;
}

RigidMatch matchLandmarkHierarchies(const GeometricHierarchy& query,
                                    const GeometricHierarchy& candidate,
                                    const HierarchyMatchParams& params,
                                    const std::vector<PolygonPair>* polygon_pairs) {
  RigidMatch result;
  std::vector<std::pair<int, int>> tri_pairs;
  const auto corr = matchHierarchies(query, candidate, params, polygon_pairs, &tri_pairs,
                                     &result.matched_polygons);
  result.correspondences = int(corr.size());
  if (query.points.size() < 2 || candidate.points.size() < 2) return result;

  // Hypotheses: one rigid fit per matched triangle (its three vertex correspondences), those of
  // matched polygons first (at most alpha, sampled), then the triangle tier.
  std::vector<std::pair<int, int>> hypotheses = tri_pairs;
  if (int(hypotheses.size()) > params.ransac_hypotheses) {
    std::mt19937 rng(params.seed);
    std::shuffle(hypotheses.begin(), hypotheses.end(), rng);
    hypotheses.resize(std::max(1, params.ransac_hypotheses));
  }
  if (params.triangle_tier_hypotheses > 0) {
    const auto tier = matchTrianglesDirectly(query, candidate, params, tri_pairs);
    hypotheses.insert(hypotheses.end(), tier.begin(), tier.end());
  }
  if (hypotheses.empty()) return result;
  const PointGrid fine(candidate.points, std::max(1e-3, params.inlier_distance));
  const PointGrid coarse(candidate.points, std::max(1e-3, params.overlap_radius));
  // Preemptive test on a fixed subset of the query landmarks (every k-th) before the full score.
  std::vector<int> probe;
  const int probe_size = std::min<int>(params.probe_landmarks, int(query.points.size()));
  for (int i = 0; i < probe_size; ++i)
    probe.push_back(int(size_t(i) * query.points.size() / probe_size));
  const int probe_min = std::max(3, int(std::ceil(params.min_inlier_ratio * probe_size * 0.5)));
  Scored best;
  for (const auto& [qa, cb] : hypotheses) {
    const HierarchyTriangle& tq = query.triangles[qa];
    const HierarchyTriangle& tc = candidate.triangles[cb];
    const int r = bestRotation(tq, tc);
    std::vector<Eigen::Vector2d> a, b;
    for (int i = 0; i < 3; ++i) {
      a.push_back(query.points[tq.v[i]]);
      b.push_back(candidate.points[tc.v[(i + r) % 3]]);
    }
    const Eigen::Isometry2d T = fitRigid2d(a, b);
    int probe_hits = 0;
    for (int i : probe)
      probe_hits += fine.nearest(T * query.points[i], params.inlier_distance) >= 0;
    if (probe_hits < probe_min) continue;
    Scored s = associate(T, query.points, candidate.points, fine, coarse, params);
    if (s.associations.size() > best.associations.size() ||
        (s.associations.size() == best.associations.size() && s.sum_d2 < best.sum_d2))
      best = std::move(s);
    // beta: a clearly good hypothesis ends the search.
    if (int(best.associations.size()) >= params.min_inliers &&
        best.associations.size() >= params.early_exit_ratio * std::max(1, best.overlap))
      break;
  }
  // Refinement: least squares on the inliers, re-associated, twice.
  for (int iter = 0; iter < 2 && best.associations.size() >= 3; ++iter) {
    std::vector<Eigen::Vector2d> a, b;
    for (const auto& [i, j] : best.associations) {
      a.push_back(query.points[i]);
      b.push_back(candidate.points[j]);
    }
    Scored s = associate(fitRigid2d(a, b), query.points, candidate.points, fine, coarse, params);
    if (s.associations.size() >= best.associations.size()) best = std::move(s);
  }
  result.transform = best.transform;
  result.associations = best.associations;
  result.inliers = int(best.associations.size());
  result.overlap = best.overlap;
  result.inlier_ratio = best.overlap > 0 ? double(result.inliers) / best.overlap : 0.0;
  result.rms = result.inliers > 0 ? std::sqrt(best.sum_d2 / result.inliers) : 0.0;
  result.accepted =
      result.inliers >= params.min_inliers && result.inlier_ratio >= params.min_inlier_ratio;
  return result;
}

}  // namespace osm_graph_slam
