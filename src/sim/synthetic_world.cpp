#include "osm_graph_slam/sim/synthetic_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace osm_graph_slam {
namespace {

constexpr double kNoHit = std::numeric_limits<double>::infinity();

/// Ray (origin o, unit direction d) against an extruded oriented box: slab test in its frame.
double intersectBox(const SyntheticBox& box, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const double c = std::cos(box.yaw), s = std::sin(box.yaw);
  const Eigen::Vector2d rel = o.head<2>() - box.center;
  const double ox = c * rel.x() + s * rel.y(), oy = -s * rel.x() + c * rel.y();
  const double dx = c * d.x() + s * d.y(), dy = -s * d.x() + c * d.y();
  double t0 = 0.0, t1 = kNoHit;
  const double origin[3] = {ox, oy, o.z()};
  const double dir[3] = {dx, dy, d.z()};
  const double lo[3] = {-box.half_size.x(), -box.half_size.y(), 0.0};
  const double hi[3] = {box.half_size.x(), box.half_size.y(), box.height};
  for (int i = 0; i < 3; ++i) {
    if (std::abs(dir[i]) < 1e-12) {
      if (origin[i] < lo[i] || origin[i] > hi[i]) return kNoHit;
      continue;
    }
    double ta = (lo[i] - origin[i]) / dir[i], tb = (hi[i] - origin[i]) / dir[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return kNoHit;
  }
  return t0 > 1e-6 ? t0 : kNoHit;
}

double intersectPole(const SyntheticPole& pole, const Eigen::Vector3d& o,
                     const Eigen::Vector3d& d) {
  const Eigen::Vector2d rel = o.head<2>() - pole.center;
  const double a = d.head<2>().squaredNorm();
  if (a < 1e-12) return kNoHit;
  const double b = 2.0 * rel.dot(d.head<2>());
  const double c = rel.squaredNorm() - pole.radius * pole.radius;
  const double disc = b * b - 4 * a * c;
  if (disc < 0) return kNoHit;
  const double t = (-b - std::sqrt(disc)) / (2 * a);
  if (t <= 1e-6) return kNoHit;
  const double z = o.z() + t * d.z();
  return (z >= 0.0 && z <= pole.height) ? t : kNoHit;
}

}  // namespace

PointCloudPtr simulateSyntheticScan(const SyntheticWorld& world, const Eigen::Vector2d& position,
                                    double yaw, const SyntheticLidarParams& params, uint32_t seed) {
  std::vector<const SyntheticBox*> boxes;
  std::vector<const SyntheticPole*> poles;
  for (const auto& b : world.boxes) {
    if ((b.center - position).norm() < params.max_range + b.half_size.norm()) boxes.push_back(&b);
  }
  for (const auto& p : world.poles) {
    if ((p.center - position).norm() < params.max_range + p.radius) poles.push_back(&p);
  }
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, params.noise_stddev);
  const Eigen::Vector3d origin(position.x(), position.y(), params.sensor_height);
  auto cloud = std::make_shared<PointCloud>();
  cloud->reserve(static_cast<size_t>(params.beams) * params.columns / 2);
  for (int col = 0; col < params.columns; ++col) {
    const double azimuth = 2.0 * M_PI * col / params.columns;  // in the sensor frame
    for (int beam = 0; beam < params.beams; ++beam) {
      const double elevation =
          (params.min_elevation_deg + (params.max_elevation_deg - params.min_elevation_deg) * beam /
                                          std::max(1, params.beams - 1)) *
          M_PI / 180.0;
      const Eigen::Vector3d local(std::cos(elevation) * std::cos(azimuth),
                                  std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      const Eigen::Vector3d dir(std::cos(yaw) * local.x() - std::sin(yaw) * local.y(),
                                std::sin(yaw) * local.x() + std::cos(yaw) * local.y(), local.z());
      double t = dir.z() < -1e-9 ? -origin.z() / dir.z() : kNoHit;
      for (const auto* b : boxes) t = std::min(t, intersectBox(*b, origin, dir));
      for (const auto* p : poles) t = std::min(t, intersectPole(*p, origin, dir));
      if (!(t < params.max_range)) continue;
      const double range = t + noise(rng);
      PointT pt;
      pt.x = static_cast<float>(range * local.x());
      pt.y = static_cast<float>(range * local.y());
      pt.z = static_cast<float>(range * local.z());
      pt.intensity = static_cast<float>(beam);
      cloud->push_back(pt);
    }
  }
  return cloud;
}

SyntheticWorld makeLoopTown(double length_x, double length_y, double facade_period, uint32_t seed) {
  SyntheticWorld world;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double setback = 8.0;  // street half width to the facades
  // Repetitive facade street along y = 0: identical buildings both sides, identical poles.
  // Intersections at both ends stay open.
  for (double x = facade_period; x <= length_x - facade_period; x += facade_period) {
    for (double side : {-1.0, 1.0}) {
      SyntheticBox b;
      b.half_size = {0.35 * facade_period, 6.0};
      b.center = {x, side * (setback + b.half_size.y())};
      b.height = 10.0;
      world.boxes.push_back(b);
      world.poles.push_back({{x + 0.5 * facade_period, side * (setback - 2.5)}, 0.15, 7.0});
    }
  }
  // Other three streets: irregular buildings, poles and cars.
  auto street = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const Eigen::Vector2d dir = (b - a).normalized();
    const Eigen::Vector2d left(-dir.y(), dir.x());
    const double heading = std::atan2(dir.y(), dir.x());
    const double len = (b - a).norm();
    for (double side : {-1.0, 1.0}) {
      double s = 10.0 + 6.0 * u(rng);
      while (s < len - 10.0) {
        SyntheticBox box;
        const double w = 6.0 + 14.0 * u(rng);
        box.half_size = {0.5 * w, 4.0 + 6.0 * u(rng)};
        const double back = setback + 1.5 * u(rng) + box.half_size.y();
        box.center = a + dir * (s + 0.5 * w) + left * side * back;
        box.yaw = heading + 0.15 * (u(rng) - 0.5);
        box.height = 4.0 + 18.0 * u(rng);
        world.boxes.push_back(box);
        if (u(rng) < 0.6) {
          world.poles.push_back(
              {a + dir * (s + w * u(rng)) + left * side * (setback - 2.0 - u(rng)),
               0.1 + 0.25 * u(rng), 3.0 + 6.0 * u(rng)});
        }
        if (u(rng) < 0.4) {
          SyntheticBox car;
          car.half_size = {2.2, 0.9};
          car.height = 1.5;
          car.yaw = heading;
          car.center = a + dir * (s + w * u(rng)) + left * side * (setback - 4.5);
          world.boxes.push_back(car);
        }
        s += w + 2.0 + 10.0 * u(rng);
      }
    }
  };
  street({length_x, 0.0}, {length_x, length_y});
  street({length_x, length_y}, {0.0, length_y});
  street({0.0, length_y}, {0.0, 0.0});
  return world;
}

std::vector<Eigen::Vector3d> loopTownRoute(double length_x, double length_y, double extra_distance,
                                           double spacing, double offset, double lateral_offset) {
  const std::vector<Eigen::Vector2d> corners = {{0, 0},        {length_x, 0}, {length_x, length_y},
                                                {0, length_y}, {0, 0},        {extra_distance, 0}};
  std::vector<Eigen::Vector3d> out;
  double s = offset;  // distance of the next pose from the start of the current segment
  for (size_t i = 0; i + 1 < corners.size(); ++i) {
    const Eigen::Vector2d a = corners[i], b = corners[i + 1];
    const double len = (b - a).norm();
    const Eigen::Vector2d dir = (b - a) / len;
    const Eigen::Vector2d left(-dir.y(), dir.x());
    for (; s < len; s += spacing) {
      const Eigen::Vector2d p = a + dir * s + left * lateral_offset;
      out.emplace_back(p.x(), p.y(), std::atan2(dir.y(), dir.x()));
    }
    s -= len;
  }
  return out;
}

}  // namespace osm_graph_slam
