#pragma once
// A seeded GNSS constellation for the canyon model: satellites far above a flat ENU world whose
// directions drift slowly across the sky (a great circle each, at a GPS-like angular rate).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace osm_graph_slam::sim {

struct ConstellationParams {
  int min_satellites = 8;            ///< drawn above the mask at the drive's start (inclusive)
  int max_satellites = 14;           ///< (inclusive)
  double elevation_mask_deg = 10.0;  ///< the receiver ignores satellites below
  /// Angular speed across the sky [deg/min]: a GPS satellite rises and sets in about six hours.
  double sky_rate_deg_per_min = 0.5;
  /// Satellites sit this far from the ENU origin (flat-Earth simplification; the real range is
  /// 20,200-25,600 km). Far enough that directions are equal all over a city.
  double distance_m = 2.02e7;
};

/// One satellite's path on the sky: u(t) = cos(w t) u0 + sin(w t) v0 (unit ENU directions).
struct SatelliteTrack {
  Eigen::Vector3d start_direction = Eigen::Vector3d::UnitZ();   ///< u0, from the ENU origin
  Eigen::Vector3d motion_direction = Eigen::Vector3d::UnitX();  ///< v0, perpendicular to u0
  double rate_rad_s = 0.0;                                      ///< w
};

class Constellation {
 public:
  /// About min..max satellites, uniform over the sky above the mask (in solid angle), each
  /// moving along its own great circle; deterministic in seed.
  static Constellation draw(const ConstellationParams& params, uint64_t seed);
  /// From given tracks (tests).
  Constellation(std::vector<SatelliteTrack> tracks, double distance_m);

  size_t size() const { return tracks_.size(); }
  Eigen::Vector3d direction(size_t satellite, double t) const;  ///< unit, ENU
  Eigen::Vector3d position(size_t satellite, double t) const;   ///< ENU [m]
  static double elevation(const Eigen::Vector3d& direction);    ///< [rad]

 private:
  std::vector<SatelliteTrack> tracks_;
  double distance_m_ = 2.02e7;
};

}  // namespace osm_graph_slam::sim
