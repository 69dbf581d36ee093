#pragma once
// Reading the OSM stage's parameters from any ParamReader with the keys of
// config/osm_buffer.yaml: the buffer's radii and retry waits, and the Overpass client's settings
// prefixed "overpass_" (both at the top level of that file).
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/osm/osm_buffer.h"
#include "osm_graph_slam/osm/overpass_client.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, OsmBufferParams& params);
void readParams(const ParamReader& reader, OverpassParams& params);

}  // namespace osm_graph_slam
