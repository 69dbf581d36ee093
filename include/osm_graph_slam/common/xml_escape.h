#pragma once
// Escaping text for XML attribute values (OSM XML writers).
#include <string>

namespace osm_graph_slam {

std::string xmlEscape(const std::string& text);

}  // namespace osm_graph_slam
