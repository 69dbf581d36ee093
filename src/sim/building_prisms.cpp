#include "osm_graph_slam/sim/building_prisms.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "osm_graph_slam/common/polygon2d.h"

namespace osm_graph_slam::sim {
namespace {

double cross2(const Eigen::Vector2d& u, const Eigen::Vector2d& v) {
  return u.x() * v.y() - u.y() * v.x();
}

/// The walls of one building, normals pointing out whatever the ring's orientation.
void appendFacades(const SimBuilding& building, int index, std::vector<Facade>& out) {
  const Polygon2& ring = building.outline;
  const double outward = polygonSignedArea(ring) >= 0.0 ? 1.0 : -1.0;
  for (size_t i = 0; i < ring.size(); ++i) {
    Facade f;
    f.a = ring[i];
    f.b = ring[(i + 1) % ring.size()];
    const Eigen::Vector2d edge = f.b - f.a;
    if (edge.norm() < 1e-6) continue;
    // Right of a counter-clockwise edge is outside.
    f.normal = outward * Eigen::Vector2d(edge.y(), -edge.x()).normalized();
    f.base_z = building.base_z;
    f.top_z = building.top_z;
    f.building = index;
    out.push_back(f);
  }
}

}  // namespace

BuildingPrisms::BuildingPrisms(const std::vector<SimBuilding>& buildings, double cell_size)
    : cell_size_(cell_size) {
  max_top_z_ = -std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < buildings.size(); ++i) {
    appendFacades(buildings[i], int(i), facades_);
    max_top_z_ = std::max(max_top_z_, buildings[i].top_z);
  }
  buildGrid();
}

Eigen::Vector2i BuildingPrisms::cellOf(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d c = (p - grid_min_) / cell_size_;
  return Eigen::Vector2i(std::clamp(int(std::floor(c.x())), 0, std::max(nx_ - 1, 0)),
                         std::clamp(int(std::floor(c.y())), 0, std::max(ny_ - 1, 0)));
}

void BuildingPrisms::buildGrid() {
  if (facades_.empty()) return;
  Eigen::Vector2d lo = facades_.front().a, hi = lo;
  for (const Facade& f : facades_) {
    lo = lo.cwiseMin(f.a).cwiseMin(f.b);
    hi = hi.cwiseMax(f.a).cwiseMax(f.b);
  }
  grid_min_ = lo;
  nx_ = int(std::floor((hi.x() - lo.x()) / cell_size_)) + 1;
  ny_ = int(std::floor((hi.y() - lo.y()) / cell_size_)) + 1;
  cells_.assign(size_t(nx_) * size_t(ny_), {});
  for (size_t i = 0; i < facades_.size(); ++i) {
    const Eigen::Vector2i c0 = cellOf(facades_[i].a.cwiseMin(facades_[i].b));
    const Eigen::Vector2i c1 = cellOf(facades_[i].a.cwiseMax(facades_[i].b));
    for (int y = c0.y(); y <= c1.y(); ++y)
      for (int x = c0.x(); x <= c1.x(); ++x) cells_[size_t(y) * nx_ + x].push_back(int(i));
  }
}

std::vector<int> BuildingPrisms::facadesNear(const Eigen::Vector2d& p, double radius) const {
  std::vector<int> out;
  if (cells_.empty()) return out;
  const Eigen::Vector2d r(radius, radius);
  // Entirely outside the grid: nothing near (clamping would otherwise pick the border cells).
  const Eigen::Vector2d grid_max = grid_min_ + cell_size_ * Eigen::Vector2d(nx_, ny_);
  if (((p + r).array() < grid_min_.array()).any() || ((p - r).array() > grid_max.array()).any())
    return out;
  const Eigen::Vector2i c0 = cellOf(p - r), c1 = cellOf(p + r);
  for (int y = c0.y(); y <= c1.y(); ++y)
    for (int x = c0.x(); x <= c1.x(); ++x) {
      const auto& cell = cells_[size_t(y) * nx_ + x];
      out.insert(out.end(), cell.begin(), cell.end());
    }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

bool BuildingPrisms::blocked(const std::vector<int>& candidates, const Eigen::Vector3d& origin,
                             const Eigen::Vector3d& direction, double length,
                             int skip_facade) const {
  const Eigen::Vector2d o = origin.head<2>(), d = direction.head<2>();
  for (int i : candidates) {
    if (i == skip_facade) continue;
    const Facade& f = facades_[size_t(i)];
    const Eigen::Vector2d edge = f.b - f.a;
    const double denom = cross2(d, edge);
    if (std::abs(denom) < 1e-12) continue;  // parallel: a prism is entered through another wall
    const Eigen::Vector2d ao = f.a - o;
    const double t = cross2(ao, edge) / denom;  // along the path (3-D distance: direction is unit)
    const double s = cross2(ao, d) / denom;     // along the edge
    if (s < 0.0 || s > 1.0 || t <= 1e-6 || t >= length) continue;
    const double z = origin.z() + t * direction.z();
    if (z >= f.base_z && z <= f.top_z) return true;
  }
  return false;
}

bool BuildingPrisms::specularPoint(int index, const Eigen::Vector3d& antenna,
                                   const Eigen::Vector3d& satellite,
                                   SpecularReflection& reflection) const {
  const Facade& f = facades_[size_t(index)];
  const Eigen::Vector3d n(f.normal.x(), f.normal.y(), 0.0);
  const Eigen::Vector3d a(f.a.x(), f.a.y(), 0.0);
  const double antenna_side = (antenna - a).dot(n), satellite_side = (satellite - a).dot(n);
  // Both in front of the wall: the signal comes from outside and bounces back outside.
  if (antenna_side <= 0.0 || satellite_side <= 0.0) return false;
  const Eigen::Vector3d image = satellite - 2.0 * satellite_side * n;
  const Eigen::Vector3d to_image = image - antenna;
  const double t = antenna_side / (antenna_side + satellite_side);  // the plane's crossing
  const Eigen::Vector3d q = antenna + t * to_image;
  const Eigen::Vector2d edge = f.b - f.a;
  const double s = (q.head<2>() - f.a).dot(edge) / edge.squaredNorm();
  if (s < 0.0 || s > 1.0 || q.z() < f.base_z || q.z() > f.top_z) return false;
  reflection.facade = index;
  reflection.point = q;
  reflection.extra_path_m = to_image.norm() - (satellite - antenna).norm();
  return true;
}

bool BuildingPrisms::shortestReflection(const std::vector<int>& candidates,
                                        const Eigen::Vector3d& antenna,
                                        const Eigen::Vector3d& satellite, double max_distance,
                                        SpecularReflection& reflection) const {
  std::vector<SpecularReflection> found;
  for (int i : candidates) {
    SpecularReflection r;
    if (!specularPoint(i, antenna, satellite, r)) continue;
    if ((r.point.head<2>() - antenna.head<2>()).norm() > max_distance) continue;
    found.push_back(r);
  }
  // Shortest first (the earliest, usually strongest echo); ties by facade for determinism.
  std::sort(found.begin(), found.end(), [](const auto& x, const auto& y) {
    return x.extra_path_m != y.extra_path_m ? x.extra_path_m < y.extra_path_m : x.facade < y.facade;
  });
  for (const SpecularReflection& r : found) {
    const Eigen::Vector3d leg_in = (satellite - r.point).normalized();
    const Eigen::Vector3d leg_out = r.point - antenna;
    const double out_length = leg_out.norm();
    if (blocked(candidates, antenna, leg_out / out_length, out_length - 1e-6, r.facade)) continue;
    if (blocked(candidates, r.point, leg_in, (satellite - r.point).norm(), r.facade)) continue;
    reflection = r;
    return true;
  }
  return false;
}

}  // namespace osm_graph_slam::sim
