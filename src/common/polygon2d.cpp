#include "osm_graph_slam/common/polygon2d.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace osm_graph_slam {

double pointSegmentDistance(const Eigen::Vector2d& p, const LineSegment2& s) {
  const Eigen::Vector2d d = s.end - s.start;
  const double l2 = d.squaredNorm();
  if (l2 <= 0.0) return (p - s.start).norm();
  const double t = std::clamp((p - s.start).dot(d) / l2, 0.0, 1.0);
  return (p - (s.start + t * d)).norm();
}

bool pointInPolygon(const Eigen::Vector2d& p, const Polygon2& polygon) {
  bool inside = false;
  const size_t n = polygon.size();
  for (size_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

std::vector<LineSegment2> polygonSegments(const Polygon2& polygon) {
  std::vector<LineSegment2> out;
  const size_t n = polygon.size();
  if (n < 2) return out;
  for (size_t i = 0; i < n; ++i) {
    if (n == 2 && i == 1) break;  // an open two-point "polygon" is one wall
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[(i + 1) % n];
    if ((b - a).norm() > 1e-9) out.emplace_back(a, b);
  }
  return out;
}

double distanceToPolygon(const Eigen::Vector2d& p, const Polygon2& polygon) {
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < polygon.size(); ++i) {
    const LineSegment2 edge(polygon[i], polygon[(i + 1) % polygon.size()]);
    best = std::min(best, pointSegmentDistance(p, edge));
  }
  return best;
}

Polygon2 transformPolygon(const Polygon2& polygon, const Pose2& T) {
  Polygon2 out;
  out.reserve(polygon.size());
  for (const auto& v : polygon) out.push_back(T.transform(v));
  return out;
}

double polygonSignedArea(const Polygon2& p) {
  double a = 0.0;
  for (size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector2d& u = p[i];
    const Eigen::Vector2d& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * a;
}

}  // namespace osm_graph_slam
