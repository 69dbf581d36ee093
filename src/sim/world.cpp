#include "osm_graph_slam/sim/world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace osm_graph_slam::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = 1e-6;

inline double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

/// True if segment [a, a+e] touches the axis-aligned box [lo, hi] (bounding boxes overlap and
/// the box corners are not all strictly on one side of the segment's line).
bool segmentTouchesBox(const Eigen::Vector2d& a, const Eigen::Vector2d& e,
                       const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  const Eigen::Vector2d b = a + e;
  if (std::max(a.x(), b.x()) < lo.x() || std::min(a.x(), b.x()) > hi.x() ||
      std::max(a.y(), b.y()) < lo.y() || std::min(a.y(), b.y()) > hi.y()) {
    return false;
  }
  const Eigen::Vector2d corners[4] = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
  int pos = 0, neg = 0;
  for (const auto& c : corners) {
    const double s = cross2(e, c - a);
    if (s > 1e-9) ++pos;
    if (s < -1e-9) ++neg;
  }
  return !(pos == 4 || neg == 4);
}

}  // namespace

const char* labelName(SimLabel label) {
  switch (label) {
    case SimLabel::kNone:
      return "none";
    case SimLabel::kGround:
      return "ground";
    case SimLabel::kBuilding:
      return "building";
    case SimLabel::kTree:
      return "tree";
    case SimLabel::kCar:
      return "car";
    case SimLabel::kFence:
      return "fence";
    case SimLabel::kPole:
      return "pole";
    case SimLabel::kMoving:
      return "moving";
  }
  return "?";
}

double GroundModel::height(double x, double y) const {
  Eigen::Vector2d g;
  return height(x, y, g);
}

double GroundModel::height(double x, double y, Eigen::Vector2d& gradient) const {
  double z = 0.0;
  gradient.setZero();
  for (int i = 0; i < 3; ++i) {
    const double k = 2.0 * M_PI / wavelength[i];
    const double cx = std::cos(direction[i]), cy = std::sin(direction[i]);
    const double arg = k * (cx * x + cy * y) + phase[i];
    z += amplitude[i] * std::sin(arg);
    const double dz = amplitude[i] * k * std::cos(arg);
    gradient.x() += dz * cx;
    gradient.y() += dz * cy;
  }
  return z;
}

double GroundModel::maxSlope() const {
  double s = 0.0;
  for (int i = 0; i < 3; ++i) s += amplitude[i] * 2.0 * M_PI / wavelength[i];
  return s;
}

double Primitive::footprintRadius() const {
  switch (kind) {
    case kCylinder:
    case kSphere:
      return radius;
    case kBox:
      return half_extent.norm();
  }
  return radius;
}

Eigen::Vector2d MovingObject::positionAt(double t) const {
  const double length = (end - start).norm();
  if (length < kEps || speed <= 0.0) return start;
  // Triangle wave: start -> end -> start ...
  const double period = 2.0 * length / speed;
  double s = std::fmod(t + phase, period);
  if (s < 0) s += period;
  const double d = s * speed;
  const double along = d <= length ? d : 2.0 * length - d;
  return start + (end - start) * (along / length);
}

double MovingObject::headingAt(double t) const {
  const double length = (end - start).norm();
  const double period = length > kEps && speed > 0.0 ? 2.0 * length / speed : 1.0;
  double s = std::fmod(t + phase, period);
  if (s < 0) s += period;
  const Eigen::Vector2d dir = end - start;
  const double yaw = std::atan2(dir.y(), dir.x());
  return s * speed <= length ? yaw : wrapAngle(yaw + M_PI);
}

bool intersectPrimitive(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                        double t_max, double& t_out, double& cos_incidence) {
  switch (p.kind) {
    case Primitive::kCylinder: {
      const Eigen::Vector2d oc(o.x() - p.center.x(), o.y() - p.center.y());
      const double a = d.x() * d.x() + d.y() * d.y();
      if (a < 1e-12) return false;
      const double b = oc.x() * d.x() + oc.y() * d.y();
      const double c = oc.squaredNorm() - p.radius * p.radius;
      const double disc = b * b - a * c;
      if (disc < 0.0 || c < 0.0) return false;  // miss, or origin inside
      const double t = (-b - std::sqrt(disc)) / a;
      if (t <= kEps || t >= t_max) return false;
      const double z = o.z() + t * d.z();
      if (z < p.z0 || z > p.z1) return false;
      const Eigen::Vector2d n = (oc + t * Eigen::Vector2d(d.x(), d.y())) / p.radius;
      cos_incidence = std::abs(n.x() * d.x() + n.y() * d.y());
      t_out = t;
      return true;
    }
    case Primitive::kSphere: {
      const Eigen::Vector3d oc = o - Eigen::Vector3d(p.center.x(), p.center.y(), p.sphere_z);
      const double b = oc.dot(d);
      const double c = oc.squaredNorm() - p.radius * p.radius;
      const double disc = b * b - c;
      if (disc < 0.0 || c < 0.0) return false;
      const double t = -b - std::sqrt(disc);
      if (t <= kEps || t >= t_max) return false;
      const Eigen::Vector3d n = (oc + t * d) / p.radius;
      cos_incidence = std::abs(n.dot(d));
      t_out = t;
      return true;
    }
    case Primitive::kBox: {
      const double c = std::cos(p.yaw), s = std::sin(p.yaw);
      const double ox = o.x() - p.center.x(), oy = o.y() - p.center.y();
      const double lo[3] = {c * ox + s * oy, -s * ox + c * oy, o.z()};
      const double ld[3] = {c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z()};
      const double mn[3] = {-p.half_extent.x(), -p.half_extent.y(), p.z0};
      const double mx[3] = {p.half_extent.x(), p.half_extent.y(), p.z1};
      double t0 = kEps, t1 = t_max;
      int axis = -1;
      for (int k = 0; k < 3; ++k) {
        if (std::abs(ld[k]) < 1e-12) {
          if (lo[k] < mn[k] || lo[k] > mx[k]) return false;
          continue;
        }
        double ta = (mn[k] - lo[k]) / ld[k], tb = (mx[k] - lo[k]) / ld[k];
        if (ta > tb) std::swap(ta, tb);
        if (ta > t0) {
          t0 = ta;
          axis = k;
        }
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
      }
      if (axis < 0) return false;  // origin inside the box
      cos_incidence = std::abs(ld[axis]);
      t_out = t0;
      return true;
    }
  }
  return false;
}

void World::finalize() {
  walls_.clear();
  for (size_t b = 0; b < buildings.size(); ++b) {
    const auto& ring = buildings[b].outline;
    for (size_t i = 0; i < ring.size(); ++i) {
      const Eigen::Vector2d a = ring[i], c = ring[(i + 1) % ring.size()];
      if ((c - a).norm() < 1e-6) continue;
      walls_.push_back({a, c - a, buildings[b].base_z, buildings[b].top_z, int32_t(b)});
    }
  }
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  auto grow = [&](const Eigen::Vector2d& p, double r) {
    lo = lo.cwiseMin(p - Eigen::Vector2d(r, r));
    hi = hi.cwiseMax(p + Eigen::Vector2d(r, r));
  };
  for (const auto& w : walls_) {
    grow(w.a, 0.0);
    grow(w.a + w.e, 0.0);
  }
  for (const auto& p : primitives) grow(p.center, p.footprintRadius());
  if (!(lo.x() <= hi.x())) {
    lo = Eigen::Vector2d(-1.0, -1.0);
    hi = Eigen::Vector2d(1.0, 1.0);
  }
  grid_min_ = lo - Eigen::Vector2d(2 * cell_size, 2 * cell_size);
  nx_ = static_cast<int>(std::ceil((hi.x() - grid_min_.x()) / cell_size)) + 2;
  ny_ = static_cast<int>(std::ceil((hi.y() - grid_min_.y()) / cell_size)) + 2;
  if (double(nx_) * ny_ > 5e7) throw std::runtime_error("sim world too large for its grid");

  std::vector<std::vector<int32_t>> cells(static_cast<size_t>(nx_) * ny_);
  auto cellRange = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b, int& x0, int& x1,
                       int& y0, int& y1) {
    x0 = std::clamp(int(std::floor((std::min(a.x(), b.x()) - grid_min_.x()) / cell_size)), 0,
                    nx_ - 1);
    x1 = std::clamp(int(std::floor((std::max(a.x(), b.x()) - grid_min_.x()) / cell_size)), 0,
                    nx_ - 1);
    y0 = std::clamp(int(std::floor((std::min(a.y(), b.y()) - grid_min_.y()) / cell_size)), 0,
                    ny_ - 1);
    y1 = std::clamp(int(std::floor((std::max(a.y(), b.y()) - grid_min_.y()) / cell_size)), 0,
                    ny_ - 1);
  };
  for (size_t i = 0; i < walls_.size(); ++i) {
    const auto& w = walls_[i];
    int x0, x1, y0, y1;
    cellRange(w.a, w.a + w.e, x0, x1, y0, y1);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d clo = grid_min_ + cell_size * Eigen::Vector2d(x, y);
        const Eigen::Vector2d margin(1e-3, 1e-3);
        if (segmentTouchesBox(w.a, w.e, clo - margin,
                              clo + Eigen::Vector2d(cell_size, cell_size) + margin)) {
          cells[size_t(y) * nx_ + x].push_back(int32_t(i));
        }
      }
    }
  }
  for (size_t i = 0; i < primitives.size(); ++i) {
    const double r = primitives[i].footprintRadius();
    int x0, x1, y0, y1;
    cellRange(primitives[i].center - Eigen::Vector2d(r, r),
              primitives[i].center + Eigen::Vector2d(r, r), x0, x1, y0, y1);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) cells[size_t(y) * nx_ + x].push_back(-1 - int32_t(i));
    }
  }
  cell_start_.assign(cells.size() + 1, 0);
  items_.clear();
  for (size_t c = 0; c < cells.size(); ++c) {
    cell_start_[c] = static_cast<uint32_t>(items_.size());
    items_.insert(items_.end(), cells[c].begin(), cells[c].end());
  }
  cell_start_.back() = static_cast<uint32_t>(items_.size());
}

bool World::castGround(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_range,
                       double& t_hit) const {
  // Newton on f(t) = o.z + t d.z - g(o.xy + t d.xy), started from the tangent plane at o.
  Eigen::Vector2d grad;
  double g = ground.height(o.x(), o.y(), grad);
  double denom = grad.x() * d.x() + grad.y() * d.y() - d.z();
  if (denom < 1e-4) {
    // Ray runs parallel to or away from the ground near the sensor: allow only gentle slopes up.
    if (d.z() > ground.maxSlope()) return false;
    denom = std::max(denom, 1e-4);
  }
  double t = (o.z() - g) / denom;
  for (int it = 0; it < 6; ++it) {
    if (!(t > 0.0) || t > 1.5 * max_range) return false;
    const double x = o.x() + t * d.x(), y = o.y() + t * d.y();
    g = ground.height(x, y, grad);
    const double f = o.z() + t * d.z() - g;
    const double df = d.z() - (grad.x() * d.x() + grad.y() * d.y());
    if (df > -1e-6) return false;
    const double step = f / df;
    t -= step;
    if (std::abs(step) < 1e-5) break;
  }
  const double x = o.x() + t * d.x(), y = o.y() + t * d.y();
  if (!(t > 0.0) || t > max_range || std::abs(o.z() + t * d.z() - ground.height(x, y)) > 1e-3) {
    return false;
  }
  t_hit = t;
  return true;
}

std::vector<Primitive> World::movingSnapshot(double t) const {
  std::vector<Primitive> out;
  out.reserve(moving.size());
  for (const auto& m : moving) {
    Primitive p = m.shape;
    p.center = m.positionAt(t);
    p.yaw = m.headingAt(t);
    const double gz = ground.height(p.center.x(), p.center.y());
    p.z0 += gz;
    p.z1 += gz;
    p.label = SimLabel::kMoving;
    out.push_back(p);
  }
  return out;
}

bool World::castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range,
                    double t, RayHit& hit) const {
  return castRay(origin, dir, max_range, movingSnapshot(t), hit);
}

bool World::castRay(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_range,
                    const std::vector<Primitive>& moving_snapshot, RayHit& hit) const {
  if (!finalized()) throw std::logic_error("World::castRay before finalize()");
  double best = max_range;
  hit = RayHit();
  double ground_t;
  if (castGround(o, d, max_range, ground_t)) {
    best = ground_t;
    Eigen::Vector2d grad;
    const Eigen::Vector3d p = o + ground_t * d;
    ground.height(p.x(), p.y(), grad);
    const Eigen::Vector3d n = Eigen::Vector3d(-grad.x(), -grad.y(), 1.0).normalized();
    hit.label = SimLabel::kGround;
    hit.reflectivity = ground_reflectivity;
    hit.cos_incidence = std::abs(n.dot(d));
  }
  for (size_t i = 0; i < moving_snapshot.size(); ++i) {
    const Primitive& p = moving_snapshot[i];
    // Cheap 2D cull: distance from the footprint centre to the ray's ground track.
    const Eigen::Vector2d oc = p.center - o.head<2>();
    const Eigen::Vector2d d2 = d.head<2>();
    const double dd = d2.squaredNorm();
    const double along = dd > 1e-12 ? oc.dot(d2) / dd : 0.0;
    const double r = p.footprintRadius();
    if ((oc - along * d2).squaredNorm() > r * r) continue;
    double tt, ci;
    if (intersectPrimitive(p, o, d, best, tt, ci)) {
      best = tt;
      hit.label = p.label;
      hit.object = int32_t(i);
      hit.reflectivity = p.reflectivity;
      hit.cos_incidence = ci;
    }
  }

  const Eigen::Vector2d o2 = o.head<2>(), d2 = d.head<2>();
  auto testItem = [&](int32_t item) {
    if (item >= 0) {
      const Wall& w = walls_[item];
      const double denom = d2.x() * w.e.y() - d2.y() * w.e.x();
      if (std::abs(denom) < 1e-12) return;
      const Eigen::Vector2d ao = w.a - o2;
      const double tt = (ao.x() * w.e.y() - ao.y() * w.e.x()) / denom;
      if (tt <= kEps || tt >= best) return;
      const double u = (ao.x() * d2.y() - ao.y() * d2.x()) / denom;
      if (u < 0.0 || u > 1.0) return;
      const double z = o.z() + tt * d.z();
      if (z < w.z0 || z > w.z1) return;
      best = tt;
      const SimBuilding& b = buildings[w.building];
      hit.label = SimLabel::kBuilding;
      hit.object = w.building;
      hit.reflectivity = b.reflectivity;
      hit.cos_incidence = std::abs(denom) / w.e.norm();
    } else {
      const int32_t pi = -1 - item;
      double tt, ci;
      if (intersectPrimitive(primitives[pi], o, d, best, tt, ci)) {
        best = tt;
        hit.label = primitives[pi].label;
        hit.object = pi;
        hit.reflectivity = primitives[pi].reflectivity;
        hit.cos_incidence = ci;
      }
    }
  };
  if (!use_grid) {  // reference: every wall and primitive
    for (size_t i = 0; i < walls_.size(); ++i) testItem(int32_t(i));
    for (size_t i = 0; i < primitives.size(); ++i) testItem(-1 - int32_t(i));
    if (hit.label == SimLabel::kNone) return false;
    hit.range = best;
    return true;
  }
  // 2D DDA over the grid, limited to [0, best].
  const Eigen::Vector2d hi = grid_min_ + cell_size * Eigen::Vector2d(nx_, ny_);
  double t_enter = 0.0, t_exit = best;
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d2[k]) < 1e-12) {
      if (o2[k] < grid_min_[k] || o2[k] > hi[k]) t_enter = kInf;  // never inside the grid
      continue;
    }
    double ta = (grid_min_[k] - o2[k]) / d2[k], tb = (hi[k] - o2[k]) / d2[k];
    if (ta > tb) std::swap(ta, tb);
    t_enter = std::max(t_enter, ta);
    t_exit = std::min(t_exit, tb);
  }
  if (t_enter <= t_exit) {
    const Eigen::Vector2d p0 = o2 + t_enter * d2;
    int ix = std::clamp(int(std::floor((p0.x() - grid_min_.x()) / cell_size)), 0, nx_ - 1);
    int iy = std::clamp(int(std::floor((p0.y() - grid_min_.y()) / cell_size)), 0, ny_ - 1);
    const int sx = d2.x() > 0 ? 1 : -1, sy = d2.y() > 0 ? 1 : -1;
    const double dtx = std::abs(d2.x()) > 1e-12 ? cell_size / std::abs(d2.x()) : kInf;
    const double dty = std::abs(d2.y()) > 1e-12 ? cell_size / std::abs(d2.y()) : kInf;
    double tmx = std::abs(d2.x()) > 1e-12
                     ? (grid_min_.x() + (ix + (sx > 0 ? 1 : 0)) * cell_size - o2.x()) / d2.x()
                     : kInf;
    double tmy = std::abs(d2.y()) > 1e-12
                     ? (grid_min_.y() + (iy + (sy > 0 ? 1 : 0)) * cell_size - o2.y()) / d2.y()
                     : kInf;
    while (true) {
      const size_t cell = size_t(iy) * nx_ + ix;
      for (uint32_t k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) testItem(items_[k]);
      const double cell_exit = std::min(tmx, tmy);
      if (best <= cell_exit || cell_exit >= t_exit) break;
      if (tmx < tmy) {
        ix += sx;
        tmx += dtx;
        if (ix < 0 || ix >= nx_) break;
      } else {
        iy += sy;
        tmy += dty;
        if (iy < 0 || iy >= ny_) break;
      }
    }
  }
  if (hit.label == SimLabel::kNone) return false;
  hit.range = best;
  return true;
}

}  // namespace osm_graph_slam::sim
