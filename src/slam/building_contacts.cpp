#include "osm_graph_slam/slam/building_contacts.h"

#include <algorithm>
#include <cmath>

#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {
namespace {

struct Wall {
  Eigen::Vector2d p, q;  ///< ends
  Eigen::Vector2d u;     ///< unit direction p -> q
  Eigen::Vector2d n;     ///< unit outward normal
  double length;
};

std::vector<Wall> outwardWalls(const Polygon2& outline, double min_length) {
  const double side = polygonSignedArea(outline) >= 0.0 ? 1.0 : -1.0;  // CCW: outside is right
  std::vector<Wall> walls;
  for (size_t i = 0; i < outline.size(); ++i) {
    Wall w;
    w.p = outline[i];
    w.q = outline[(i + 1) % outline.size()];
    w.length = (w.q - w.p).norm();
    if (w.length < min_length) continue;
    w.u = (w.q - w.p) / w.length;
    w.n = side * Eigen::Vector2d(w.u.y(), -w.u.x());
    walls.push_back(w);
  }
  return walls;
}

// The contact of wall a with the facing wall b, if they face each other closely enough.
bool facing(const Wall& a, const Wall& b, const BuildingContactParams& p, BuildingContact* c) {
  if (a.n.dot(b.n) > -std::cos(p.max_angle_deg * M_PI / 180.0)) return false;
  const double d = b.n.dot(0.5 * (a.p + a.q) - b.p);  // > 0: a's wall outside b (a gap)
  if (std::abs(d) > p.max_distance) return false;
  const double t0 = a.u.dot(b.p - a.p), t1 = a.u.dot(b.q - a.p);
  const double lo = std::max(0.0, std::min(t0, t1)), hi = std::min(a.length, std::max(t0, t1));
  const double shared = hi - lo;
  if (shared < std::min(p.min_shared_fraction * std::min(a.length, b.length), p.min_shared_length))
    return false;
  c->a_ends[0] = a.p + lo * a.u;
  c->a_ends[1] = a.p + hi * a.u;
  c->b_point = b.p;
  c->b_normal = b.n;
  c->distance = d;
  c->shared_length = shared;
  return true;
}

}  // namespace

std::vector<BuildingContact> findBuildingContacts(const std::vector<Polygon2>& outlines,
                                                  const BuildingContactParams& params) {
  std::vector<std::vector<Wall>> walls;
  std::vector<const Polygon2*> polygons;
  for (const auto& outline : outlines) {
    walls.push_back(outwardWalls(outline, params.min_wall_length));
    polygons.push_back(&outline);
  }
  std::vector<BuildingContact> contacts;
  for (const auto& [i, j] : nearbyPolygonPairs(polygons, params.max_distance)) {
    BuildingContact best, candidate;
    for (const Wall& a : walls[i])
      for (const Wall& b : walls[j])
        if (facing(a, b, params, &candidate) && candidate.shared_length > best.shared_length)
          best = candidate;
    if (best.shared_length <= 0.0) continue;
    best.a = i;
    best.b = j;
    contacts.push_back(best);
  }
  return contacts;
}

}  // namespace osm_graph_slam
