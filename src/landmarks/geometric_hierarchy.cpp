#include "osm_graph_slam/landmarks/geometric_hierarchy.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <set>
#include <unordered_map>

namespace osm_graph_slam {

namespace {

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

uint64_t edgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (uint64_t(uint32_t(a)) << 32) | uint32_t(b);
}

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

HierarchyTriangle makeTriangle(const std::array<int, 3>& v,
                               const std::vector<Eigen::Vector2d>& pts) {
  HierarchyTriangle t;
  t.v = v;
  for (int i = 0; i < 3; ++i) t.side[i] = (pts[v[(i + 1) % 3]] - pts[v[i]]).norm();
  t.longest = int(std::max_element(t.side.begin(), t.side.end()) - t.side.begin());
  t.sorted_sides = t.side;
  std::sort(t.sorted_sides.begin(), t.sorted_sides.end(), std::greater<double>());
  return t;
}

/// Area centroid of a closed ring (the vertex mean if the area vanishes).
Eigen::Vector2d ringCentroid(const std::vector<Eigen::Vector2d>& ring) {
  double area2 = 0.0;
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < ring.size(); ++i) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[(i + 1) % ring.size()];
    const double w = cross(a, b);
    area2 += w;
    c += w * (a + b);
  }
  if (std::abs(area2) < 1e-9) {
    c.setZero();
    for (const auto& p : ring) c += p;
    return c / double(ring.size());
  }
  return c / (3.0 * area2);
}

/// Boundary of a set of counter-clockwise triangles as one closed vertex walk.
std::vector<int> traceBoundary(const std::vector<int>& tris,
                               const std::vector<HierarchyTriangle>& all) {
  std::set<std::pair<int, int>> directed;
  for (int t : tris)
    for (int i = 0; i < 3; ++i) directed.insert({all[t].v[i], all[t].v[(i + 1) % 3]});
  std::multimap<int, int> outgoing;  // boundary edges: their reverse is not in the set
  for (const auto& [a, b] : directed)
    if (!directed.count({b, a})) outgoing.insert({a, b});
  std::vector<int> ring;
  if (outgoing.empty()) return ring;
  const int start = outgoing.begin()->first;
  int current = start;
  const size_t max_steps = outgoing.size();
  for (size_t step = 0; step < max_steps; ++step) {
    const auto it = outgoing.find(current);
    if (it == outgoing.end()) break;
    ring.push_back(current);
    const int next = it->second;
    outgoing.erase(it);
    current = next;
    if (current == start) break;
  }
  return ring;
}

}  // namespace

std::vector<std::array<int, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points) {
  std::vector<std::array<int, 3>> out;
  std::vector<int> valid;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    valid.push_back(int(i));
    lo = lo.cwiseMin(points[i]);
    hi = hi.cwiseMax(points[i]);
  }
  if (valid.size() < 3) return out;
  // Subdiv2D takes an integer rectangle and float points: work relative to the lower corner.
  const Eigen::Vector2d extent = hi - lo;
  if (extent.maxCoeff() > 1e6) return out;  // not landmark coordinates
  cv::Subdiv2D subdiv(
      cv::Rect(-2, -2, int(std::ceil(extent.x())) + 5, int(std::ceil(extent.y())) + 5));
  std::unordered_map<int, int> vertex_to_point;
  for (int i : valid) {
    const Eigen::Vector2d p = points[i] - lo;
    const int vid = subdiv.insert(cv::Point2f(float(p.x()), float(p.y())));
    vertex_to_point.emplace(vid, i);  // a duplicate keeps the first index
  }
  std::vector<int> leading;
  subdiv.getLeadingEdgeList(leading);
  std::set<std::array<int, 3>> seen;
  for (int e0 : leading) {
    for (int e : {e0, e0 ^ 2}) {
      const int e1 = subdiv.getEdge(e, cv::Subdiv2D::NEXT_AROUND_LEFT);
      const int e2 = subdiv.getEdge(e1, cv::Subdiv2D::NEXT_AROUND_LEFT);
      if (subdiv.getEdge(e2, cv::Subdiv2D::NEXT_AROUND_LEFT) != e) continue;
      std::array<int, 3> tri;
      bool ok = true;
      const int edges[3] = {e, e1, e2};
      for (int k = 0; k < 3 && ok; ++k) {
        const auto it = vertex_to_point.find(subdiv.edgeOrg(edges[k]));
        ok = it != vertex_to_point.end();  // the virtual outer vertices are not ours
        if (ok) tri[k] = it->second;
      }
      if (!ok) continue;
      const double orient = cross(points[tri[1]] - points[tri[0]], points[tri[2]] - points[tri[0]]);
      if (std::abs(orient) < 1e-12) continue;  // collinear sliver
      if (orient < 0) std::swap(tri[1], tri[2]);
      std::array<int, 3> key = tri;
      std::sort(key.begin(), key.end());
      if (seen.insert(key).second) out.push_back(tri);
    }
  }
  return out;
}

Eigen::VectorXf polygonDescriptor(const std::vector<Eigen::Vector2d>& ring,
                                  const GeometricHierarchyParams& params) {
  const int n = std::max(8, params.descriptor_samples);
  const int k_max = std::max(1, std::min(params.descriptor_harmonics, n / 2));
  if (ring.size() < 3) return Eigen::VectorXf();
  double perimeter = 0.0;
  for (size_t i = 0; i < ring.size(); ++i)
    perimeter += (ring[(i + 1) % ring.size()] - ring[i]).norm();
  if (!(perimeter > 1e-9)) return Eigen::VectorXf();
  const Eigen::Vector2d centroid = ringCentroid(ring);
  // Centroid distance at n points spaced perimeter / n along the boundary, from ring[0].
  std::vector<double> r(n);
  const double step = perimeter / n;
  size_t edge = 0;
  double edge_start = 0.0;  // arc length at ring[edge]
  double edge_len = (ring[1] - ring[0]).norm();
  for (int s = 0; s < n; ++s) {
    const double arc = s * step;
    while (arc > edge_start + edge_len && edge + 1 < ring.size()) {
      edge_start += edge_len;
      ++edge;
      edge_len = (ring[(edge + 1) % ring.size()] - ring[edge]).norm();
    }
    const double f = edge_len > 0 ? std::clamp((arc - edge_start) / edge_len, 0.0, 1.0) : 0.0;
    const Eigen::Vector2d p = ring[edge] + f * (ring[(edge + 1) % ring.size()] - ring[edge]);
    r[s] = (p - centroid).norm();
  }
  // A different start vertex is a circular shift of r: the DFT magnitudes do not change.
  Eigen::VectorXf d(k_max);
  for (int k = 0; k < k_max; ++k) {
    double re = 0.0, im = 0.0;
    for (int s = 0; s < n; ++s) {
      const double a = -2.0 * M_PI * k * s / n;
      re += r[s] * std::cos(a);
      im += r[s] * std::sin(a);
    }
    d[k] = float(std::hypot(re, im) / n);
  }
  return d;
}

GeometricHierarchy buildGeometricHierarchy(const std::vector<Eigen::Vector2d>& points,
                                           const GeometricHierarchyParams& params) {
  GeometricHierarchy h;
  h.points = points;
  for (const auto& v : delaunayTriangles(points)) {
    HierarchyTriangle t = makeTriangle(v, points);
    if (t.sorted_sides[0] <= params.max_edge_length) h.triangles.push_back(t);
  }
  // Urquhart graph: every edge that is the longest side of one of its triangles is dropped, and
  // the triangles on both sides of a dropped edge belong to one polygon.
  std::unordered_map<uint64_t, std::vector<int>> edge_triangles;
  for (size_t t = 0; t < h.triangles.size(); ++t)
    for (int i = 0; i < 3; ++i)
      edge_triangles[edgeKey(h.triangles[t].v[i], h.triangles[t].v[(i + 1) % 3])].push_back(int(t));
  std::set<uint64_t> dropped;
  UnionFind components(h.triangles.size());
  for (size_t t = 0; t < h.triangles.size(); ++t) {
    const HierarchyTriangle& tri = h.triangles[t];
    const uint64_t key = edgeKey(tri.v[tri.longest], tri.v[(tri.longest + 1) % 3]);
    dropped.insert(key);
    for (int other : edge_triangles[key])
      if (other != int(t)) components.unite(int(t), other);
  }
  for (const auto& [key, tris] : edge_triangles)
    if (!dropped.count(key)) h.urquhart_edges.push_back({int(key >> 32), int(key & 0xffffffffu)});
  std::sort(h.urquhart_edges.begin(), h.urquhart_edges.end());

  std::map<int, std::vector<int>> groups;  // ordered: deterministic polygon order
  for (size_t t = 0; t < h.triangles.size(); ++t) groups[components.find(int(t))].push_back(int(t));
  for (auto& [root, tris] : groups) {
    UrquhartPolygon poly;
    poly.triangles = tris;
    poly.vertices = traceBoundary(tris, h.triangles);
    if (poly.vertices.size() < 3) continue;
    std::vector<Eigen::Vector2d> ring;
    for (int v : poly.vertices) ring.push_back(points[v]);
    poly.centroid = ringCentroid(ring);
    for (size_t i = 0; i < ring.size(); ++i)
      poly.perimeter += (ring[(i + 1) % ring.size()] - ring[i]).norm();
    poly.descriptor = polygonDescriptor(ring, params);
    if (poly.descriptor.size() == 0) continue;
    h.polygons.push_back(std::move(poly));
  }
  return h;
}

}  // namespace osm_graph_slam
