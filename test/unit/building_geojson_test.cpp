#include <gtest/gtest.h>

#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/slam/map_export.h"

using namespace osm_graph_slam;

TEST(BuildingGeoJson, RoundTripKeepsIdsTagsAndCoordinates) {
  Building a;
  a.id = 123456789012;
  a.version = 7;  // an editor uploads the corrected way against it
  a.tags = {{"building", "yes"}, {"building:levels", "4"}};
  a.outline_geo = {{49.01, 8.41}, {49.0101, 8.41}, {49.0101, 8.4102}, {49.01, 8.4102}};
  Building b;
  b.id = -42;  // a multipolygon relation
  b.part = 2;  // its third outer ring
  b.outline_geo = {{49.02, 8.42}, {49.0201, 8.42}, {49.0201, 8.4201}};
  const BuildingFileResult r = parseBuildingsGeoJson(buildingsToGeoJson({a, b}));
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.buildings.size(), 2u);
  EXPECT_EQ(r.buildings[0].id, a.id);
  EXPECT_EQ(r.buildings[0].tags, a.tags);
  ASSERT_EQ(r.buildings[0].outline_geo.size(), 4u);  // closing vertex removed again
  EXPECT_DOUBLE_EQ(r.buildings[0].outline_geo[2].lat, 49.0101);
  EXPECT_DOUBLE_EQ(r.buildings[0].outline_geo[2].lon, 8.4102);
  EXPECT_EQ(r.buildings[1].id, -42);
  EXPECT_EQ(r.buildings[0].version, 7);
  EXPECT_EQ(r.buildings[0].part, 0);
  EXPECT_EQ(r.buildings[1].part, 2);
  EXPECT_EQ(r.buildings[1].version, 0);
  EXPECT_NE(buildingsToOsmXml({a}).find("<way id='123456789012' version='7'>"), std::string::npos);
}

TEST(BuildingGeoJson, MalformedInputIsAnErrorNotACrash) {
  EXPECT_FALSE(parseBuildingsGeoJson("{").ok);
  EXPECT_FALSE(parseBuildingsGeoJson("[1,2]").ok);
  const auto r = parseBuildingsGeoJson(
      R"({"type":"FeatureCollection","features":[{"geometry":{"type":"Point","coordinates":[1,2]}}]})");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("not a Polygon"), std::string::npos);
  EXPECT_FALSE(readBuildingsGeoJson("/nonexistent.geojson").ok);
}
