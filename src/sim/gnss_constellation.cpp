#include "osm_graph_slam/sim/gnss_constellation.h"

#include <Eigen/Geometry>
#include <cmath>

#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr uint64_t kConstellationTag = 0x636f6e7374ULL;  // "const"

Eigen::Vector3d directionFromAzEl(double azimuth, double elevation) {
  // Azimuth clockwise from north, as a receiver reports it.
  return Eigen::Vector3d(std::sin(azimuth) * std::cos(elevation),
                         std::cos(azimuth) * std::cos(elevation), std::sin(elevation));
}

/// A uniform direction of motion on the sky at u (tangent to the unit sphere).
Eigen::Vector3d tangentAt(const Eigen::Vector3d& u, double angle) {
  const Eigen::Vector3d east = Eigen::Vector3d::UnitZ().cross(u).normalized();
  const Eigen::Vector3d north = u.cross(east);
  return std::cos(angle) * east + std::sin(angle) * north;
}

}  // namespace

Constellation::Constellation(std::vector<SatelliteTrack> tracks, double distance_m)
    : tracks_(std::move(tracks)), distance_m_(distance_m) {}

Constellation Constellation::draw(const ConstellationParams& p, uint64_t seed) {
  SimRng rng(hashCombine(seed, kConstellationTag));
  const int count = rng.uniformInt(p.min_satellites, std::max(p.min_satellites, p.max_satellites));
  const double sin_mask = std::sin(p.elevation_mask_deg * kDeg);
  std::vector<SatelliteTrack> tracks(size_t(std::max(count, 0)));
  for (SatelliteTrack& s : tracks) {
    // Uniform in solid angle above the mask: sin(elevation) uniform.
    const double elevation = std::asin(rng.uniform(sin_mask, 1.0));
    const double azimuth = rng.uniform(0.0, 2.0 * M_PI);
    s.start_direction = directionFromAzEl(azimuth, std::min(elevation, 89.9 * kDeg));
    s.motion_direction = tangentAt(s.start_direction, rng.uniform(0.0, 2.0 * M_PI));
    s.rate_rad_s = p.sky_rate_deg_per_min * kDeg / 60.0;
  }
  return Constellation(std::move(tracks), p.distance_m);
}

Eigen::Vector3d Constellation::direction(size_t i, double t) const {
  const SatelliteTrack& s = tracks_[i];
  const double angle = s.rate_rad_s * t;
  return std::cos(angle) * s.start_direction + std::sin(angle) * s.motion_direction;
}

Eigen::Vector3d Constellation::position(size_t i, double t) const {
  return distance_m_ * direction(i, t);
}

double Constellation::elevation(const Eigen::Vector3d& d) {
  return std::asin(std::clamp(d.z() / d.norm(), -1.0, 1.0));
}

}  // namespace osm_graph_slam::sim
