#pragma once
// ENU <-> geodetic around a fixed origin (the first valid GPS fix), GeographicLib LocalCartesian.
#include <Eigen/Core>
#include <memory>

#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

class EnuConverter {
 public:
  EnuConverter(double lat0, double lon0, double alt0 = 0.0);
  ~EnuConverter();
  EnuConverter(const EnuConverter& other);
  EnuConverter& operator=(const EnuConverter& other);

  Eigen::Vector3d toEnu(double lat, double lon, double alt = 0.0) const;
  Eigen::Vector2d toEnu(const GeoPoint& p) const;
  /// Returns (lat, lon, alt).
  Eigen::Vector3d toGeodetic(const Eigen::Vector3d& enu) const;
  GeoPoint toGeoPoint(const Eigen::Vector2d& enu) const;

  double originLat() const { return lat0_; }
  double originLon() const { return lon0_; }
  double originAlt() const { return alt0_; }

  /// Fills outline_enu, reference_pose (lowest-x vertex, heading 0) and wall segments.
  void project(Building& building) const;
  void project(Road& road) const;

 private:
  double lat0_, lon0_, alt0_;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace osm_graph_slam
