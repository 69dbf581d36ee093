#include "osm_graph_slam/osm/building_set.h"

#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {

std::vector<std::pair<size_t, size_t>> findOverlappingBuildings(
    const std::vector<Building>& buildings, double min_area) {
  std::vector<const Polygon2*> outlines;
  for (const auto& b : buildings) outlines.push_back(&b.outline_enu);
  std::vector<std::pair<size_t, size_t>> pairs;
  for (const auto& [i, j] : nearbyPolygonPairs(outlines, 0.0))
    if (polygonOverlapArea(buildings[i].outline_enu, buildings[j].outline_enu) > min_area)
      pairs.emplace_back(i, j);
  return pairs;
}

bool isRoofOnly(const Building& building) {
  const auto tag = [&](const char* key) {
    const auto it = building.tags.find(key);
    return it == building.tags.end() ? std::string() : it->second;
  };
  const std::string type = tag("building");
  return type == "roof" || type == "carport" || tag("building:walls") == "no";
}

}  // namespace osm_graph_slam
