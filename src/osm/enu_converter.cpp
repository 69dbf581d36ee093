#include "osm_graph_slam/osm/enu_converter.h"

#include <GeographicLib/LocalCartesian.hpp>
#include <algorithm>
#include <limits>

namespace osm_graph_slam {

struct EnuConverter::Impl {
  GeographicLib::LocalCartesian cartesian;
  Impl(double lat0, double lon0, double alt0) : cartesian(lat0, lon0, alt0) {}
};

EnuConverter::EnuConverter(double lat0, double lon0, double alt0)
    : lat0_(lat0), lon0_(lon0), alt0_(alt0), impl_(std::make_unique<Impl>(lat0, lon0, alt0)) {}

EnuConverter::~EnuConverter() = default;

EnuConverter::EnuConverter(const EnuConverter& other)
    : lat0_(other.lat0_),
      lon0_(other.lon0_),
      alt0_(other.alt0_),
      impl_(std::make_unique<Impl>(*other.impl_)) {}

EnuConverter& EnuConverter::operator=(const EnuConverter& other) {
  if (this != &other) {
    lat0_ = other.lat0_;
    lon0_ = other.lon0_;
    alt0_ = other.alt0_;
    impl_ = std::make_unique<Impl>(*other.impl_);
  }
  return *this;
}

Eigen::Vector3d EnuConverter::toEnu(double lat, double lon, double alt) const {
  Eigen::Vector3d enu;
  impl_->cartesian.Forward(lat, lon, alt, enu.x(), enu.y(), enu.z());
  return enu;
}

Eigen::Vector2d EnuConverter::toEnu(const GeoPoint& p) const {
  // Map geometry lies on the origin's altitude: a 2D ENU point is the tangent-plane position.
  return toEnu(p.lat, p.lon, alt0_).head<2>();
}

Eigen::Vector3d EnuConverter::toGeodetic(const Eigen::Vector3d& enu) const {
  Eigen::Vector3d lla;
  impl_->cartesian.Reverse(enu.x(), enu.y(), enu.z(), lla.x(), lla.y(), lla.z());
  return lla;
}

GeoPoint EnuConverter::toGeoPoint(const Eigen::Vector2d& enu) const {
  // Inverse of toEnu(GeoPoint): find the point at the origin's altitude whose ENU (x, y) match.
  // Its ENU z (earth curvature, about -d^2/2R) is unknown; a fixed point iteration on z
  // converges to sub-micrometre after two steps even at tens of kilometres.
  double z = 0.0;
  Eigen::Vector3d lla = toGeodetic(Eigen::Vector3d(enu.x(), enu.y(), z));
  for (int i = 0; i < 3; ++i) {
    z = toEnu(lla.x(), lla.y(), alt0_).z();
    lla = toGeodetic(Eigen::Vector3d(enu.x(), enu.y(), z));
  }
  return {lla.x(), lla.y()};
}

void EnuConverter::project(Building& building) const {
  building.outline_enu.clear();
  building.segments.clear();
  building.outline_enu.reserve(building.outline_geo.size());
  for (const GeoPoint& p : building.outline_geo) building.outline_enu.push_back(toEnu(p));

  building.reference_pose = Pose2();
  double lowest_x = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& v : building.outline_enu) lowest_x = std::min(lowest_x, v.x());
  // Vertices within 1 mm of the lowest x (a wall along north) tie; the lower y wins so the
  // corner does not flip between them under numerical noise.
  double lowest_y = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& v : building.outline_enu) {
    if (v.x() <= lowest_x + 1e-3 && v.y() < lowest_y) {
      lowest_y = v.y();
      building.reference_pose = Pose2(v.x(), v.y(), 0.0);
    }
  }

  const size_t n = building.outline_enu.size();
  if (n < 2) return;
  building.segments.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    building.segments.emplace_back(building.outline_enu[i], building.outline_enu[(i + 1) % n]);
  }
}

void EnuConverter::project(Road& road) const {
  road.nodes_enu.clear();
  road.nodes_enu.reserve(road.nodes_geo.size());
  for (const GeoPoint& p : road.nodes_geo) road.nodes_enu.push_back(toEnu(p));
}

}  // namespace osm_graph_slam
