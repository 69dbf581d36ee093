#include "osm_graph_slam/io/building_geojson.h"

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "osm_graph_slam/io/trajectory_io.h"

namespace osm_graph_slam {
namespace {

using nlohmann::json;

json ringToJson(const std::vector<GeoPoint>& ring) {
  json coords = json::array();
  for (const auto& p : ring) coords.push_back({p.lon, p.lat});
  if (!ring.empty()) coords.push_back({ring.front().lon, ring.front().lat});  // closed ring
  return coords;
}

std::vector<GeoPoint> ringFromJson(const json& coords) {
  std::vector<GeoPoint> ring;
  for (const auto& c : coords) ring.push_back({c.at(1).get<double>(), c.at(0).get<double>()});
  if (ring.size() > 1 && ring.front().lat == ring.back().lat && ring.front().lon == ring.back().lon)
    ring.pop_back();
  return ring;
}

}  // namespace

std::string buildingsToGeoJson(const std::vector<Building>& buildings) {
  json features = json::array();
  for (const auto& b : buildings) {
    json feature = {
        {"type", "Feature"},
        {"geometry", {{"type", "Polygon"}, {"coordinates", {ringToJson(b.outline_geo)}}}},
        {"properties", {{"id", b.id}, {"tags", b.tags}}}};
    // A relation's outer rings share its id; a replay or a merge tells them apart by part.
    if (b.part != 0) feature["properties"]["part"] = b.part;
    if (b.version > 0) feature["properties"]["version"] = b.version;
    features.push_back(std::move(feature));
  }
  json doc = {{"type", "FeatureCollection"}, {"features", std::move(features)}};
  return doc.dump(1) + "\n";
}

bool writeBuildingsGeoJson(const std::string& path, const std::vector<Building>& buildings,
                           std::string* error) {
  return writeFileAtomically(path, buildingsToGeoJson(buildings), error);
}

BuildingFileResult parseBuildingsGeoJson(const std::string& text) {
  BuildingFileResult result;
  try {
    const json doc = json::parse(text);
    if (doc.value("type", "") != "FeatureCollection") {
      result.error = "GeoJSON is not a FeatureCollection";
      return result;
    }
    size_t index = 0;
    for (const auto& f : doc.at("features")) {
      const json& geometry = f.at("geometry");
      if (geometry.value("type", "") != "Polygon") {
        result.error = "feature " + std::to_string(index) + " is not a Polygon";
        return result;
      }
      Building b;
      b.outline_geo = ringFromJson(geometry.at("coordinates").at(0));
      const json& props = f.value("properties", json::object());
      // "osm_id" is what the simulator's buildings_true.geojson calls it.
      b.id =
          props.contains("id") ? props.value("id", int64_t{0}) : props.value("osm_id", int64_t{0});
      if (props.contains("tags")) b.tags = props.at("tags").get<OsmTags>();
      b.part = props.value("part", 0);
      b.version = props.value("version", 0);
      result.buildings.push_back(std::move(b));
      ++index;
    }
    result.ok = true;
  } catch (const std::exception& e) {
    result.error = std::string("malformed GeoJSON: ") + e.what();
  }
  return result;
}

BuildingFileResult readBuildingsGeoJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    BuildingFileResult r;
    r.error = "cannot open '" + path + "'";
    return r;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  BuildingFileResult r = parseBuildingsGeoJson(ss.str());
  if (!r.ok) r.error = path + ": " + r.error;
  return r;
}

}  // namespace osm_graph_slam
