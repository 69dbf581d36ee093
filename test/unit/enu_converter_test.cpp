// ENU <-> geodetic (GeographicLib LocalCartesian) and building projection.
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>
#include <cmath>

#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/gnss_fix_lookup.h"

namespace osm_graph_slam {
namespace {

constexpr double kLat0 = 49.0111, kLon0 = 8.4240;  // Karlsruhe, KITTI drive 0005

TEST(GnssFixLookup, InterpolatesBetweenCloseFixesElseTakesTheNearestWithinTheLimit) {
  const std::vector<GnssFixSample> fixes = {
      {10.0, 49.0, 8.0, 100.0}, {10.1, 49.001, 8.002, 101.0}, {14.0, 49.01, 8.01, 110.0}};
  const auto mid = gnssFixAt(fixes, 10.025, 1.5, 0.05);
  ASSERT_TRUE(mid.has_value());
  EXPECT_NEAR(mid->lat, 49.00025, 1e-12);
  EXPECT_NEAR(mid->lon, 8.0005, 1e-12);
  EXPECT_NEAR(mid->alt, 100.25, 1e-9);
  // Between 10.1 and 14.0 the fixes are 3.9 s apart: only a fix within 0.05 s counts.
  EXPECT_FALSE(gnssFixAt(fixes, 12.0, 1.5, 0.05).has_value());
  const auto near_last = gnssFixAt(fixes, 13.97, 1.5, 0.05);
  ASSERT_TRUE(near_last.has_value());
  EXPECT_EQ(near_last->lat, 49.01);
  // Before the first and after the last fix: the nearest one, if close enough.
  EXPECT_EQ(gnssFixAt(fixes, 9.96, 1.5, 0.05)->lat, 49.0);
  EXPECT_FALSE(gnssFixAt(fixes, 9.9, 1.5, 0.05).has_value());
  EXPECT_EQ(gnssFixAt(fixes, 14.04, 1.5, 0.05)->lat, 49.01);
  EXPECT_FALSE(gnssFixAt({}, 10.0, 1.5, 0.05).has_value());
}

TEST(GnssFixLookup, KeepsTheLargerReportedDeviationAndUnknownStaysUnknown) {
  const std::vector<GnssFixSample> fixes = {{10.0, 49.0, 8.0, 100.0, 0.02},
                                            {10.1, 49.0005, 8.001, 100.5, 1.8},
                                            {10.2, 49.001, 8.002, 101.0, 0.0}};
  EXPECT_DOUBLE_EQ(gnssFixAt(fixes, 10.05, 1.5, 0.05)->std_xy, 1.8);
  EXPECT_DOUBLE_EQ(gnssFixAt(fixes, 10.15, 1.5, 0.05)->std_xy, 0.0);
  EXPECT_DOUBLE_EQ(gnssFixAt(fixes, 10.0, 1.5, 0.05)->std_xy, 0.02);
}

TEST(EnuConverter, OriginMapsToZero) {
  const EnuConverter enu(kLat0, kLon0, 112.0);
  EXPECT_LT(enu.toEnu(kLat0, kLon0, 112.0).norm(), 1e-9);
  EXPECT_LT(enu.toEnu(GeoPoint{kLat0, kLon0}).norm(), 1e-9);
}

TEST(EnuConverter, AxesAndDistancesAgreeWithGeodesics) {
  const EnuConverter enu(kLat0, kLon0);
  const GeographicLib::Geodesic& geod = GeographicLib::Geodesic::WGS84();
  double lat2, lon2;
  geod.Direct(kLat0, kLon0, 0.0, 1000.0, lat2, lon2);  // 1 km due north
  const Eigen::Vector2d north = enu.toEnu(GeoPoint{lat2, lon2});
  EXPECT_NEAR(north.x(), 0.0, 1e-3);
  EXPECT_NEAR(north.y(), 1000.0, 0.1);  // tangent plane vs geodesic: < 0.1 m at 1 km
  geod.Direct(kLat0, kLon0, 90.0, 1000.0, lat2, lon2);  // 1 km due east
  const Eigen::Vector2d east = enu.toEnu(GeoPoint{lat2, lon2});
  EXPECT_NEAR(east.x(), 1000.0, 0.1);
  EXPECT_NEAR(east.y(), 0.0, 0.1);
}

TEST(EnuConverter, RoundTripBelowOneMillimetreOver5Km) {
  const EnuConverter enu(kLat0, kLon0, 115.0);
  double worst_2d = 0.0, worst_3d = 0.0;
  for (double x = -5000.0; x <= 5000.0; x += 250.0) {
    for (double y = -5000.0; y <= 5000.0; y += 250.0) {
      const Eigen::Vector2d p(x, y);
      const Eigen::Vector2d back = enu.toEnu(enu.toGeoPoint(p));
      worst_2d = std::max(worst_2d, (back - p).norm());
      const Eigen::Vector3d p3(x, y, 30.0);
      const Eigen::Vector3d lla = enu.toGeodetic(p3);
      worst_3d = std::max(worst_3d, (enu.toEnu(lla.x(), lla.y(), lla.z()) - p3).norm());
    }
  }
  std::cout << "[ENU] worst round-trip error over +-5 km: 2D " << worst_2d * 1e3 << " mm, 3D "
            << worst_3d * 1e3 << " mm\n";
  EXPECT_LT(worst_2d, 1e-3);
  EXPECT_LT(worst_3d, 1e-3);
}

TEST(EnuConverter, CopiesAreIndependentAndEqual) {
  EnuConverter a(kLat0, kLon0);
  EnuConverter b(a);
  EnuConverter c(0.0, 0.0);
  c = a;
  const GeoPoint g{kLat0 + 0.01, kLon0 - 0.02};
  EXPECT_LT((a.toEnu(g) - b.toEnu(g)).norm(), 1e-12);
  EXPECT_LT((a.toEnu(g) - c.toEnu(g)).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(c.originLat(), kLat0);
}

TEST(EnuConverter, ProjectBuildingFillsOutlineReferenceAndWalls) {
  const EnuConverter enu(kLat0, kLon0);
  // An L-shaped building given in ENU, converted to lat/lon, projected back.
  const Polygon2 l_shape = {{110, 50}, {130, 50}, {130, 60}, {120, 60}, {120, 75}, {110, 80}};
  Building b;
  for (const auto& v : l_shape) b.outline_geo.push_back(enu.toGeoPoint(v));
  enu.project(b);
  ASSERT_EQ(b.outline_enu.size(), l_shape.size());
  for (size_t i = 0; i < l_shape.size(); ++i)
    EXPECT_LT((b.outline_enu[i] - l_shape[i]).norm(), 1e-6);
  // Two vertices share the lowest x (110): the lower y wins.
  EXPECT_NEAR(b.reference_pose.x, 110.0, 1e-6);
  EXPECT_NEAR(b.reference_pose.y, 50.0, 1e-6);
  EXPECT_EQ(b.reference_pose.theta, 0.0);
  ASSERT_EQ(b.segments.size(), l_shape.size());
  double perimeter = 0.0;
  for (const auto& s : b.segments) perimeter += s.length();
  const double expected = 20 + 10 + 10 + 15 + std::hypot(10.0, 5.0) + 30;
  EXPECT_NEAR(perimeter, expected, 1e-5);
  EXPECT_LT((b.segments.back().end - b.outline_enu.front()).norm(), 1e-12);  // ring closed

  Road r;
  r.nodes_geo = {enu.toGeoPoint({0, 0}), enu.toGeoPoint({100, -20})};
  enu.project(r);
  ASSERT_EQ(r.nodes_enu.size(), 2u);
  EXPECT_LT((r.nodes_enu[1] - Eigen::Vector2d(100, -20)).norm(), 1e-6);
}

}  // namespace
}  // namespace osm_graph_slam
