#include "osm_graph_slam/sim/forest_world.h"

#include <algorithm>
#include <cmath>

#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {

namespace {

double segmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

/// Distance from p to the nearest trail centre line.
double trailDistance(const Eigen::Vector2d& p, const std::vector<Polyline2>& trails) {
  double best = 1e300;
  for (const auto& line : trails)
    for (size_t i = 0; i + 1 < line.size(); ++i)
      best = std::min(best, segmentDistance(p, line[i], line[i + 1]));
  return best;
}

/// Smooth pseudo-random field in [-1, 1] (three plane waves): park groves where it is high.
double groveField(const Eigen::Vector2d& p, uint64_t seed) {
  SimRng rng(hashCombine(seed, 0x67726f7665ULL));
  double v = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double dir = rng.uniform(0.0, M_PI), wavelength = rng.uniform(90.0, 160.0);
    const double phase = rng.uniform(0.0, 2.0 * M_PI);
    v +=
        std::sin(2.0 * M_PI * (p.x() * std::cos(dir) + p.y() * std::sin(dir)) / wavelength + phase);
  }
  return v / 3.0;
}

Primitive cylinder(SimLabel label, const Eigen::Vector2d& c, double r, double z0, double z1,
                   float reflectivity) {
  Primitive p;
  p.kind = Primitive::kCylinder;
  p.label = label;
  p.center = c;
  p.radius = r;
  p.z0 = z0;
  p.z1 = z1;
  p.reflectivity = reflectivity;
  return p;
}

Primitive sphere(SimLabel label, const Eigen::Vector2d& c, double r, double z, float reflectivity) {
  Primitive p;
  p.kind = Primitive::kSphere;
  p.label = label;
  p.center = c;
  p.radius = r;
  p.sphere_z = z;
  p.z0 = z - r;
  p.z1 = z + r;
  p.reflectivity = reflectivity;
  return p;
}

}  // namespace

bool forestPreset(const std::string& name, ForestParams& p) {
  if (name == "dense") {
    p.min_distance = 4.0;
    p.jitter_sigma = 2.0;
  } else if (name == "intermediate") {
    p.min_distance = 7.0;
    p.jitter_sigma = 3.0;
  } else if (name == "sparse") {
    p.min_distance = 9.0;
    p.jitter_sigma = 3.5;
  } else if (name == "park") {
    p.park = true;
    p.min_distance = 7.0;
    p.jitter_sigma = 3.0;
    p.bushes_per_ha = 30.0;
    p.saplings_per_ha = 5.0;
    p.logs_per_ha = 0.0;
  } else {
    return false;
  }
  return true;
}

std::vector<Eigen::Vector2d> poissonDiscSamples(double w, double h, double min_distance,
                                                uint64_t seed, int attempts) {
  std::vector<Eigen::Vector2d> samples;
  if (!(w > 0 && h > 0 && min_distance > 0)) return samples;
  SimRng rng(hashCombine(seed, 0x706f6973736f6eULL));
  const double cell = min_distance / std::sqrt(2.0);
  const int nx = int(std::ceil(w / cell)), ny = int(std::ceil(h / cell));
  std::vector<int> grid(size_t(nx) * ny, -1);
  auto cellOf = [&](const Eigen::Vector2d& p) {
    return std::make_pair(std::min(nx - 1, int(p.x() / cell)), std::min(ny - 1, int(p.y() / cell)));
  };
  auto fits = [&](const Eigen::Vector2d& p) {
    if (p.x() < 0 || p.y() < 0 || p.x() >= w || p.y() >= h) return false;
    const auto [cx, cy] = cellOf(p);
    for (int x = std::max(0, cx - 2); x <= std::min(nx - 1, cx + 2); ++x)
      for (int y = std::max(0, cy - 2); y <= std::min(ny - 1, cy + 2); ++y) {
        const int s = grid[size_t(y) * nx + x];
        if (s >= 0 && (samples[s] - p).squaredNorm() < min_distance * min_distance) return false;
      }
    return true;
  };
  auto insert = [&](const Eigen::Vector2d& p) {
    const auto [cx, cy] = cellOf(p);
    grid[size_t(cy) * nx + cx] = int(samples.size());
    samples.push_back(p);
  };
  insert(Eigen::Vector2d(rng.uniform(0, w), rng.uniform(0, h)));
  std::vector<int> active{0};
  while (!active.empty()) {
    const size_t pick = size_t(rng.next() % active.size());
    const Eigen::Vector2d base = samples[active[pick]];
    bool placed = false;
    for (int k = 0; k < attempts && !placed; ++k) {
      const double r = min_distance * (1.0 + rng.uniform()), a = rng.uniform(0, 2 * M_PI);
      const Eigen::Vector2d p = base + r * Eigen::Vector2d(std::cos(a), std::sin(a));
      if (fits(p)) {
        active.push_back(int(samples.size()));
        insert(p);
        placed = true;
      }
    }
    if (!placed) {
      active[pick] = active.back();
      active.pop_back();
    }
  }
  return samples;
}

Scene forestScene(const ForestParams& params, const GroundModel& ground) {
  Scene scene;
  scene.world.ground = ground;
  World& world = scene.world;
  const double half = params.size / 2.0;
  SimRng rng(hashCombine(params.seed, 0x666f72657374ULL));

  // Trails: a grid of junctions (jittered), lines through them with wiggling vertices between.
  const int n = std::max(2, int(std::round(params.size / params.trail_spacing)));
  const double spacing = params.size / n;
  std::vector<std::vector<Eigen::Vector2d>> junction(n, std::vector<Eigen::Vector2d>(n));
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      junction[i][j] = Eigen::Vector2d(-half + spacing * (i + 0.5) + rng.uniform(-8, 8),
                                       -half + spacing * (j + 0.5) + rng.uniform(-8, 8));
  int64_t id = 1;
  auto addTrail = [&](const std::vector<Eigen::Vector2d>& nodes) {
    Polyline2 line;
    for (size_t k = 0; k + 1 < nodes.size(); ++k) {
      line.push_back(nodes[k]);
      const Eigen::Vector2d d = nodes[k + 1] - nodes[k];
      const Eigen::Vector2d normal = Eigen::Vector2d(-d.y(), d.x()).normalized();
      for (int s = 1; s <= 3; ++s)  // gentle bends: the vehicle heading varies along the trail
        line.push_back(nodes[k] + d * (s / 4.0) +
                       normal * rng.uniform(-params.trail_wiggle, params.trail_wiggle));
    }
    line.push_back(nodes.back());
    scene.roads.push_back(line);
    scene.road_ids.push_back(id++);
    scene.road_types.push_back(params.park ? "path" : "track");
  };
  for (int i = 0; i < n; ++i) {
    std::vector<Eigen::Vector2d> col, row;
    for (int j = 0; j < n; ++j) {
      col.push_back(junction[i][j]);
      row.push_back(junction[j][i]);
    }
    addTrail(col);
    addTrail(row);
  }
  auto clearOfTrails = [&](const Eigen::Vector2d& p, double clearance) {
    if (trailDistance(p, scene.roads) < clearance) return false;
    for (const auto& colv : junction)
      for (const auto& j : colv)
        if ((p - j).norm() < params.junction_clearance + clearance - params.trail_clearance)
          return false;
    return true;
  };

  // Trees: Poisson disc + Gaussian jitter (thesis §4.5.2), off the trails.
  const auto disc = poissonDiscSamples(params.size, params.size, params.min_distance,
                                       hashCombine(params.seed, 1));
  SimRng tree_rng(hashCombine(params.seed, 2));
  const double grove_threshold = 1.0 - 2.0 * params.park_grove_fraction;  // of a [-1, 1] field
  for (const auto& s : disc) {
    const Eigen::Vector2d c =
        s - Eigen::Vector2d(half, half) +
        params.jitter_sigma * Eigen::Vector2d(tree_rng.gaussian(), tree_rng.gaussian());
    const double radius = tree_rng.uniform(params.trunk_radius_min, params.trunk_radius_max);
    const double crown_base = tree_rng.uniform(params.crown_base_min, params.crown_base_max);
    const double crown_r = tree_rng.uniform(1.5, 3.5);
    const bool solitary = tree_rng.bernoulli(0.06);
    if (std::abs(c.x()) > half || std::abs(c.y()) > half) continue;
    if (params.park && groveField(c, params.seed) < grove_threshold && !solitary) continue;
    if (!clearOfTrails(c, params.trail_clearance + radius)) continue;
    const double gz = ground.height(c.x(), c.y());
    world.primitives.push_back(
        cylinder(SimLabel::kTree, c, radius, gz - 0.5, gz + crown_base + crown_r, 0.25f));
    world.primitives.push_back(
        sphere(SimLabel::kTree, c, crown_r, gz + crown_base + crown_r, 0.35f));
  }

  // Undergrowth and clutter (uniform over the area, off the trails).
  const double area_ha = params.size * params.size / 1e4;
  SimRng clutter_rng(hashCombine(params.seed, 3));
  auto randomPoint = [&]() {
    return Eigen::Vector2d(clutter_rng.uniform(-half, half), clutter_rng.uniform(-half, half));
  };
  for (int k = 0; k < int(params.bushes_per_ha * area_ha); ++k) {
    const Eigen::Vector2d c = randomPoint();
    const double r = clutter_rng.uniform(0.3, 1.0);
    const double z = ground.height(c.x(), c.y()) + clutter_rng.uniform(0.0, 1.5 - r);
    if (!clearOfTrails(c, 1.5 + r)) continue;
    world.primitives.push_back(sphere(SimLabel::kTree, c, r, z, 0.3f));
  }
  for (int k = 0; k < int(params.saplings_per_ha * area_ha); ++k) {
    const Eigen::Vector2d c = randomPoint();
    if (!clearOfTrails(c, 1.5)) continue;
    const double gz = ground.height(c.x(), c.y());
    world.primitives.push_back(cylinder(SimLabel::kTree, c, clutter_rng.uniform(0.02, 0.05),
                                        gz - 0.2, gz + clutter_rng.uniform(1.5, 3.5), 0.3f));
  }
  for (int k = 0; k < int(params.logs_per_ha * area_ha); ++k) {
    const Eigen::Vector2d c = randomPoint();
    if (!clearOfTrails(c, 4.0)) continue;
    Primitive log;
    log.kind = Primitive::kBox;
    log.label = SimLabel::kTree;
    log.center = c;
    log.yaw = clutter_rng.uniform(0, M_PI);
    log.half_extent = Eigen::Vector2d(clutter_rng.uniform(1.5, 3.0), 0.2);
    const double gz = ground.height(c.x(), c.y());
    log.z0 = gz - 0.2;
    log.z1 = gz + 0.4;
    log.reflectivity = 0.25f;
    world.primitives.push_back(log);
  }
  if (params.park) {
    // Lamp posts along the paths (poles: landmarks too) and benches.
    SimRng park_rng(hashCombine(params.seed, 4));
    for (const auto& line : scene.roads) {
      double carry = 0.0;
      for (size_t i = 0; i + 1 < line.size(); ++i) {
        const Eigen::Vector2d d = line[i + 1] - line[i];
        const double len = d.norm();
        const Eigen::Vector2d u = d / len, side(-u.y(), u.x());
        for (double s = params.park_lamp_spacing - carry; s < len; s += params.park_lamp_spacing) {
          const Eigen::Vector2d c =
              line[i] + u * s + side * 2.8 * (park_rng.bernoulli(0.5) ? 1 : -1);
          if (!clearOfTrails(c, 2.5)) continue;
          const double gz = ground.height(c.x(), c.y());
          world.primitives.push_back(cylinder(SimLabel::kPole, c, 0.08, gz - 0.3, gz + 4.5, 0.5f));
          if (park_rng.bernoulli(0.3)) {
            Primitive bench;
            bench.kind = Primitive::kBox;
            bench.label = SimLabel::kFence;
            bench.center = c + u * 3.0;
            bench.yaw = std::atan2(u.y(), u.x());
            bench.half_extent = Eigen::Vector2d(0.9, 0.3);
            bench.z0 = gz;
            bench.z1 = gz + 0.8;
            bench.reflectivity = 0.4f;
            if (clearOfTrails(bench.center, 2.2)) world.primitives.push_back(bench);
          }
        }
        carry = std::fmod(carry + len, params.park_lamp_spacing);
      }
    }
  }
  return scene;
}

std::vector<TrunkTruth> forestTrunks(const Scene& scene, double min_radius) {
  std::vector<TrunkTruth> out;
  for (const auto& p : scene.world.primitives)
    if (p.kind == Primitive::kCylinder &&
        (p.label == SimLabel::kTree || p.label == SimLabel::kPole) && p.radius >= min_radius)
      out.push_back({p.center, p.radius});
  return out;
}

}  // namespace osm_graph_slam::sim
