// OSM XML from memory (the Overpass answer path and, through salvage, the file path).
#include <cstdint>
#include <string>

#include "osm_graph_slam/osm/osm_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  osm_graph_slam::OsmReadOptions options;
  options.max_objects = 10'000;  // keeps one execution bounded; the limit path is fuzzed too
  options.max_nodes = 100'000;
  const osm_graph_slam::OsmData osm =
      osm_graph_slam::parseOsmXml(std::string(reinterpret_cast<const char*>(data), size), options);
  // Touch the result so nothing is optimised away.
  size_t vertices = 0;
  for (const auto& b : osm.buildings) vertices += b.outline_geo.size();
  for (const auto& r : osm.roads) vertices += r.nodes_geo.size();
  return vertices == static_cast<size_t>(-1);
}
