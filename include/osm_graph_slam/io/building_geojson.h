#pragma once
// Buildings as GeoJSON (RFC 7946: a FeatureCollection of Polygons in lon/lat, WGS84), the format
// of buildings_true.geojson (simulator) and of the corrected buildings written by save_map.
#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

struct BuildingFileResult {
  std::vector<Building> buildings;  ///< outline_geo, id and tags filled; ENU left empty
  bool ok = false;
  std::string error;
};

/// Properties written per feature: "id" (OSM id), "tags" (object).
std::string buildingsToGeoJson(const std::vector<Building>& buildings);
bool writeBuildingsGeoJson(const std::string& path, const std::vector<Building>& buildings,
                           std::string* error = nullptr);
BuildingFileResult parseBuildingsGeoJson(const std::string& text);
BuildingFileResult readBuildingsGeoJson(const std::string& path);

}  // namespace osm_graph_slam
