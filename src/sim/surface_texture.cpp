#include "osm_graph_slam/sim/surface_texture.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

/// A uniform number in [0, 1) fixed for the cell of `p` (size `cell`) and a salt per pattern.
double cellNoise(double x, double y, double z, double cell, uint64_t salt) {
  const auto index = [cell](double v) {
    return static_cast<uint64_t>(static_cast<int64_t>(std::floor(v / cell)));
  };
  const uint64_t h = hashCombine(hashCombine(hashCombine(salt, index(x)), index(y)), index(z));
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);  // 53 bits
}

double fraction(double v) {
  return v - std::floor(v);
}

/// Where `p` lies along the building's nearest wall [m from the wall's first corner].
double alongWall(const SimBuilding& building, const Eigen::Vector2d& p) {
  const Polygon2& ring = building.outline;
  double best = std::numeric_limits<double>::infinity(), along = 0.0;
  for (size_t i = 0; i < ring.size(); ++i) {
    const Eigen::Vector2d a = ring[i], b = ring[(i + 1) % ring.size()];
    const Eigen::Vector2d ab = b - a;
    const double length = ab.norm();
    if (length < 1e-6) continue;
    const double t = std::clamp((p - a).dot(ab) / length, 0.0, length);
    const double d = (a + ab * (t / length) - p).squaredNorm();
    if (d < best) {
      best = d;
      along = t;
    }
  }
  return along;
}

float ground(const World& world, const Eigen::Vector3d& p, const SurfaceTextureParams& params) {
  const double shade = cellNoise(p.x(), p.y(), 0.0, params.asphalt_cell, 0x61737068);
  if (shade < params.marking_share) return params.marking_reflectance;
  const double variation = params.asphalt_variation * (2.0 * shade - 1.0);
  return static_cast<float>(world.ground_reflectivity * (1.0 + variation));
}

float facade(const World& world, const RayHit& hit, const Eigen::Vector3d& p,
             const SurfaceTextureParams& params) {
  if (hit.object < 0 || static_cast<size_t>(hit.object) >= world.buildings.size())
    return hit.reflectivity;
  const SimBuilding& b = world.buildings[static_cast<size_t>(hit.object)];
  // Glass fills the middle of every storey and bay; the rest is the wall's own reflectivity.
  const double storey = fraction((p.z() - b.base_z) / params.storey_height);
  const double bay = fraction(alongWall(b, p.head<2>()) / params.window_spacing);
  const double margin = 0.5 * (1.0 - params.window_fill);
  const bool glass = storey > margin && storey < 1.0 - margin && bay > margin && bay < 1.0 - margin;
  return glass ? params.glass_reflectance : hit.reflectivity;
}

}  // namespace

float surfaceReflectance(const World& world, const RayHit& hit, const Eigen::Vector3d& p,
                         const SurfaceTextureParams& params) {
  if (!params.enabled) return hit.reflectivity;
  switch (hit.label) {
    case SimLabel::kGround:
      return ground(world, p, params);
    case SimLabel::kBuilding:
      return facade(world, hit, p, params);
    case SimLabel::kTree: {
      const double leaf = cellNoise(p.x(), p.y(), p.z(), params.foliage_cell, 0x6c656166);
      return static_cast<float>(hit.reflectivity * (0.4 + 1.2 * leaf));
    }
    default:
      return hit.reflectivity;
  }
}

}  // namespace osm_graph_slam::sim
