#include "osm_graph_slam/lines/line_geometry.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <boost/geometry.hpp>
#include <boost/geometry/geometries/point_xy.hpp>
#include <boost/geometry/geometries/polygon.hpp>
#include <cmath>
#include <limits>

namespace osm_graph_slam {
namespace {

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

struct Ray {
  double angle;
  double arm;
};

/// Rays from a corner at parameter s along a segment of length len and direction d.
std::vector<Ray> raysAt(double s, double len, const Eigen::Vector2d& d, double tol) {
  const double fwd = std::atan2(d.y(), d.x());
  const double back = wrapAngle(fwd + M_PI);
  if (s > tol && s < len - tol) return {{fwd, len - s}, {back, s}};  // corner inside: both sides
  if (s <= 0.5 * len) return {{fwd, len - s}};
  return {{back, s}};
}

}  // namespace

double segmentDistanceNoCoverage(const LineSegment2& source, const LineSegment2& target) {
  return 0.5 *
         (pointSegmentDistance(source.start, target) + pointSegmentDistance(source.end, target));
}

CoverageDistance segmentDistanceWithCoverage(const LineSegment2& source,
                                             const LineSegment2& target) {
  const double ls = source.length(), lt = target.length();
  const Eigen::Vector2d us = source.direction(), ut = target.direction();
  const Eigen::Vector2d ns(-us.y(), us.x()), nt(-ut.y(), ut.x());
  double sum = 0.0;
  int n = 0;
  for (const Eigen::Vector2d& p : {source.start, source.end}) {
    const double tau = (p - target.start).dot(ut);
    if (tau >= 0.0 && tau <= lt) {
      sum += std::abs((p - target.start).dot(nt));
      ++n;
    }
  }
  const double sc = (target.start - source.start).dot(us);
  const double sd = (target.end - source.start).dot(us);
  for (const auto& [q, sigma] :
       {std::make_pair(target.start, sc), std::make_pair(target.end, sd)}) {
    if (sigma >= 0.0 && sigma <= ls) {
      sum += std::abs((q - source.start).dot(ns));
      ++n;
    }
  }
  CoverageDistance out;
  if (n == 0) {
    out.distance = segmentDistanceNoCoverage(source, target);
    return out;
  }
  out.distance = sum / n;
  out.coverage = std::max(0.0, std::min(ls, std::max(sc, sd)) - std::max(0.0, std::min(sc, sd)));
  return out;
}

std::vector<LineEdge> extractEdges(const std::vector<LineSegment2>& segments, const EdgeParams& p) {
  std::vector<LineEdge> edges;
  const double min_sin = std::sin(p.min_angle_deg * M_PI / 180.0);
  const double tol = p.endpoint_tolerance;
  for (size_t i = 0; i < segments.size(); ++i) {
    const LineSegment2& a = segments[i];
    const double la = a.length();
    if (!(la > 0.0) || !a.start.allFinite() || !a.end.allFinite()) continue;
    const Eigen::Vector2d da = a.direction();
    for (size_t j = i + 1; j < segments.size(); ++j) {
      const LineSegment2& b = segments[j];
      const double lb = b.length();
      if (!(lb > 0.0) || !b.start.allFinite() || !b.end.allFinite()) continue;
      const Eigen::Vector2d db = b.direction();
      const double sin_ab = cross(da, db);
      if (std::abs(sin_ab) < min_sin) continue;
      const Eigen::Vector2d ab = b.start - a.start;
      const double s = cross(ab, db) / sin_ab;  // corner = a.start + s * da
      const double r = cross(ab, da) / sin_ab;  // corner = b.start + r * db
      const double gap_a = std::max({0.0, -s, s - la}), gap_b = std::max({0.0, -r, r - lb});
      if (gap_a > p.max_virtual_distance || gap_b > p.max_virtual_distance) continue;
      const bool inside_a = s > tol && s<la - tol, inside_b = r> tol && r < lb - tol;
      const bool angular = gap_a <= tol && gap_b <= tol && !inside_a && !inside_b;
      const Eigen::Vector2d corner = a.start + s * da;
      for (const Ray& ra : raysAt(s, la, da, tol)) {
        for (const Ray& rb : raysAt(r, lb, db, tol)) {
          LineEdge e;
          e.corner = corner;
          e.virtual_edge = !angular;
          const double ccw = wrapAngle(rb.angle - ra.angle);  // from ray a to ray b
          if (ccw > 0.0) {
            e.ray1 = ra.angle, e.ray2 = rb.angle, e.arm1 = ra.arm, e.arm2 = rb.arm;
            e.seg1 = int(i), e.seg2 = int(j), e.opening = ccw;
          } else {
            e.ray1 = rb.angle, e.ray2 = ra.angle, e.arm1 = rb.arm, e.arm2 = ra.arm;
            e.seg1 = int(j), e.seg2 = int(i), e.opening = -ccw;
          }
          edges.push_back(e);
        }
      }
    }
  }
  return edges;
}

double polygonOverlapArea(const Polygon2& a, const Polygon2& b) {
  namespace bg = boost::geometry;
  using Point = bg::model::d2::point_xy<double>;
  using Poly = bg::model::polygon<Point>;
  if (a.size() < 3 || b.size() < 3) return 0.0;
  // boost.geometry returned a whole building as the intersection of two outlines sharing a
  // nearly collinear wall (full-precision coordinates 1 cm apart); coordinates snapped to 0.1 mm
  // around a local origin avoid those near-degenerate configurations.
  const Eigen::Vector2d origin = a.front();
  auto toBoost = [&](const Polygon2& in) {
    Poly out;
    auto snap = [](double v) { return std::round(v * 1e4) * 1e-4; };
    for (const auto& v : in)
      bg::append(out.outer(), Point(snap(v.x() - origin.x()), snap(v.y() - origin.y())));
    bg::append(out.outer(), out.outer().front());
    bg::correct(out);
    return out;
  };
  try {
    const Poly pa = toBoost(a), pb = toBoost(b);
    std::vector<Poly> parts;
    bg::intersection(pa, pb, parts);
    double area = 0.0;
    for (const Poly& part : parts) area += std::abs(bg::area(part));
    return area;
  } catch (const std::exception&) {
    return 0.0;  // invalid (self-intersecting) input: no defined overlap
  }
}

namespace {

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

/// True if the open segments p0-p1 and q0-q1 cross (touching endpoints do not count).
bool segmentsCross(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& q0,
                   const Eigen::Vector2d& q1) {
  const Eigen::Vector2d r = p1 - p0, s = q1 - q0;
  const double denom = cross2(r, s);
  if (std::abs(denom) < 1e-12) return false;  // parallel: a grazing ray is not blocked
  const double t = cross2(q0 - p0, s) / denom, u = cross2(q0 - p0, r) / denom;
  constexpr double eps = 1e-6;
  return t > eps && t < 1.0 - eps && u > eps && u < 1.0 - eps;
}

bool rayBlocked(const Eigen::Vector2d& from, const Eigen::Vector2d& to, const Polygon2& polygon,
                size_t skip_edge) {
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    if (i == skip_edge) continue;
    if (segmentsCross(from, to, polygon[i], polygon[(i + 1) % n])) return true;
  }
  return false;
}

}  // namespace

std::vector<std::pair<size_t, size_t>> nearbyPolygonPairs(
    const std::vector<const Polygon2*>& polygons, double margin) {
  std::vector<Eigen::AlignedBox2d> boxes(polygons.size());
  std::vector<size_t> order;
  for (size_t i = 0; i < polygons.size(); ++i) {
    for (const auto& v : *polygons[i]) boxes[i].extend(v);
    if (boxes[i].isEmpty()) continue;
    boxes[i].min().array() -= 0.5 * margin;  // both grown by half: gaps up to margin pair
    boxes[i].max().array() += 0.5 * margin;
    order.push_back(i);
  }
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return boxes[a].min().x() < boxes[b].min().x(); });
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t k = 0; k < order.size(); ++k) {
    const Eigen::AlignedBox2d& box = boxes[order[k]];
    for (size_t l = k + 1; l < order.size() && boxes[order[l]].min().x() <= box.max().x(); ++l) {
      if (!box.intersects(boxes[order[l]])) continue;
      pairs.emplace_back(std::min(order[k], order[l]), std::max(order[k], order[l]));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

std::vector<size_t> visibleWalls(const Polygon2& outline, const Eigen::Vector2d& viewpoint,
                                 double max_range, const std::vector<const Polygon2*>& occluders) {
  std::vector<size_t> visible;
  const size_t n = outline.size();
  if (n < 3) return visible;
  const double orientation =
      polygonSignedArea(outline) >= 0.0 ? 1.0 : -1.0;  // CCW: outside is right
  size_t index = 0;  // polygonSegments' numbering (degenerate edges skipped)
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = outline[i];
    const Eigen::Vector2d& b = outline[(i + 1) % n];
    if ((b - a).norm() <= 1e-9) continue;
    const size_t wall = index++;
    const Eigen::Vector2d d = b - a;
    const Eigen::Vector2d outward = orientation * Eigen::Vector2d(d.y(), -d.x());
    if (outward.dot(viewpoint - a) <= 0.0) continue;  // seen from inside: faces away
    if (pointSegmentDistance(viewpoint, LineSegment2(a, b)) > max_range) continue;
    for (double f : {0.1, 0.5, 0.9}) {
      const Eigen::Vector2d sample = a + f * d;
      bool blocked = rayBlocked(viewpoint, sample, outline, i);
      for (const Polygon2* o : occluders) {
        if (blocked) break;
        if (o != &outline) blocked = rayBlocked(viewpoint, sample, *o, o->size());
      }
      if (!blocked) {
        visible.push_back(wall);
        break;
      }
    }
  }
  return visible;
}

}  // namespace osm_graph_slam
