#include "osm_graph_slam/sim/wall_scan_simulator.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {
namespace {

Polygon2 placed(const Polygon2& local, double x0, double y0, double yaw) {
  return transformPolygon(local, Pose2(x0, y0, yaw));
}

/// Range along a unit ray from o to the nearest wall, and that wall's building; inf if none.
std::pair<double, int> castRay(const Eigen::Vector2d& o, const Eigen::Vector2d& d,
                               const std::vector<LineSegment2>& walls,
                               const std::vector<int>& owner) {
  double best = HUGE_VAL;
  int who = -1;
  for (size_t k = 0; k < walls.size(); ++k) {
    const Eigen::Vector2d e = walls[k].end - walls[k].start;
    const double den = d.x() * e.y() - d.y() * e.x();
    if (std::abs(den) < 1e-12) continue;
    const Eigen::Vector2d w = walls[k].start - o;
    const double t = (w.x() * e.y() - w.y() * e.x()) / den;  // along the ray
    const double s = (w.x() * d.y() - w.y() * d.x()) / den;  // along the wall
    if (t > 1e-6 && s >= 0.0 && s <= 1.0 && t < best) {
      best = t;
      who = owner[k];
    }
  }
  return {best, who};
}

}  // namespace

std::vector<LineSegment2> buildingWalls(const SimBuilding& b) {
  std::vector<LineSegment2> walls = polygonSegments(b.outline);
  for (const auto& c : b.courtyards) {
    const auto inner = polygonSegments(c);
    walls.insert(walls.end(), inner.begin(), inner.end());
  }
  return walls;
}

std::vector<LineSegment2> buildingWalls(const std::vector<SimBuilding>& buildings) {
  std::vector<LineSegment2> walls;
  for (const auto& b : buildings) {
    const auto w = buildingWalls(b);
    walls.insert(walls.end(), w.begin(), w.end());
  }
  return walls;
}

PointCloudPtr simulateWallScan(const std::vector<SimBuilding>& buildings, const Pose2& pose,
                               const WallScanParams& p) {
  std::mt19937 rng(p.seed);
  std::normal_distribution<double> noise(0.0, p.range_noise);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<LineSegment2> walls;
  std::vector<int> owner;
  for (size_t b = 0; b < buildings.size(); ++b) {
    for (const auto& w : buildingWalls(buildings[b])) {
      walls.push_back(w);
      owner.push_back(int(b));
    }
  }
  auto cloud = std::make_shared<PointCloud>();
  const double h = p.sensor_height;
  auto addSensorPoint = [&](const Eigen::Vector3d& dir, double range) {
    const double r = range + noise(rng);
    PointT pt;
    pt.x = float(dir.x() * r);
    pt.y = float(dir.y() * r);
    pt.z = float(dir.z() * r);
    pt.intensity = 0.0f;
    cloud->push_back(pt);
  };
  const Eigen::Vector2d origin = pose.translation();
  for (int a = 0; a < p.beams_per_ring; ++a) {
    const double az = 2.0 * M_PI * a / p.beams_per_ring;  // sensor frame
    const double world_az = pose.theta + az;
    const auto [r2d, who] = castRay(origin, {std::cos(world_az), std::sin(world_az)}, walls, owner);
    for (int ring = 0; ring < p.rings; ++ring) {
      const double el = (p.min_elevation_deg + (p.max_elevation_deg - p.min_elevation_deg) * ring /
                                                   std::max(1, p.rings - 1)) *
                        M_PI / 180.0;
      const Eigen::Vector3d dir(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                std::sin(el));
      const double ground = el < 0.0 ? h / std::tan(-el) : HUGE_VAL;  // horizontal range
      if (ground < r2d && ground <= p.max_range) {
        addSensorPoint(dir, ground / std::cos(el));
      } else if (who >= 0 && r2d <= p.max_range) {
        const double z = r2d * std::tan(el);
        if (z <= buildings[who].height - h) addSensorPoint(dir, r2d / std::cos(el));
      }
    }
  }
  // Clutter in the sensor frame: tree canopies, poles, scattered returns.
  auto push = [&](double x, double y, double z) {
    PointT pt;
    pt.x = float(x), pt.y = float(y), pt.z = float(z), pt.intensity = 0.0f;
    cloud->push_back(pt);
  };
  for (int t = 0; t < p.trees; ++t) {
    const double ang = 2 * M_PI * unit(rng), dist = 4.0 + 8.0 * unit(rng);
    const double cx = dist * std::cos(ang), cy = dist * std::sin(ang), cz = 2.0 + 2.0 * unit(rng);
    for (int k = 0; k < 300; ++k) {
      Eigen::Vector3d v(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
      if (v.norm() > 0.5) continue;
      v *= 3.0;  // canopy radius 1.5 m
      push(cx + v.x(), cy + v.y(), cz + v.z());
    }
  }
  for (int k = 0; k < p.poles; ++k) {
    const double ang = 2 * M_PI * unit(rng), dist = 3.0 + 10.0 * unit(rng);
    for (double z = -h; z < 5.0; z += 0.1)
      push(dist * std::cos(ang) + 0.05 * unit(rng), dist * std::sin(ang) + 0.05 * unit(rng), z);
  }
  for (int k = 0; k < p.scattered_points; ++k)
    push(60.0 * (unit(rng) - 0.5), 60.0 * (unit(rng) - 0.5), -h + 8.0 * unit(rng));
  cloud->width = cloud->size();
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

SimBuilding rectangleBuilding(double x0, double y0, double w, double d, double yaw) {
  SimBuilding b;
  b.outline = placed({{0, 0}, {w, 0}, {w, d}, {0, d}}, x0, y0, yaw);
  return b;
}

SimBuilding lShapeBuilding(double x0, double y0, double w, double d, double nw, double nd,
                           double yaw) {
  SimBuilding b;
  b.outline =
      placed({{0, 0}, {w, 0}, {w, d - nd}, {w - nw, d - nd}, {w - nw, d}, {0, d}}, x0, y0, yaw);
  return b;
}

SimBuilding courtyardBuilding(double x0, double y0, double w, double d, double t, double yaw) {
  SimBuilding b;
  b.outline = placed({{0, 0}, {w, 0}, {w, d}, {0, d}}, x0, y0, yaw);
  b.courtyards.push_back(placed({{t, t}, {t, d - t}, {w - t, d - t}, {w - t, t}}, x0, y0, yaw));
  return b;
}

std::vector<SimBuilding> makeStreetScene(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<SimBuilding> out;
  const int per_side = (n + 1) / 2;
  for (int side = 0; side < 2 && int(out.size()) < n; ++side) {
    double x = -8.0 * per_side + 4.0 * unit(rng);
    for (int i = 0; i < per_side && int(out.size()) < n; ++i) {
      const double w = 9.0 + 6.0 * unit(rng), d = 9.0 + 6.0 * unit(rng);
      const double yaw = (unit(rng) - 0.5) * 6.0 * M_PI / 180.0;
      const double y0 = side == 0 ? 7.0 + 2.0 * unit(rng) : -7.0 - 2.0 * unit(rng) - d;
      SimBuilding b;
      const int kind = int(out.size()) % 5;
      if (int(out.size()) == 2)
        b = courtyardBuilding(x, y0, w + 4.0, d + 4.0, 3.5, yaw);
      else if (kind == 1 || kind == 3)
        b = lShapeBuilding(x, y0, w, d, 0.4 * w, 0.4 * d, yaw);
      else
        b = rectangleBuilding(x, y0, w, d, yaw);
      b.height = 8.0 + 10.0 * unit(rng);
      double max_x = -HUGE_VAL;
      for (const auto& v : b.outline) max_x = std::max(max_x, v.x());
      x = max_x + 2.0 + 4.0 * unit(rng);
      out.push_back(std::move(b));
    }
  }
  return out;
}

}  // namespace osm_graph_slam
