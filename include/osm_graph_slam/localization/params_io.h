#pragma once
// Reading LocalizationParams from any ParamReader with the keys of config/localization.yaml
// (registration/ and ukf/ blocks nested).
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/localization/osm_localizer.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, PoseUkfParams& params);
void readParams(const ParamReader& reader, LocalizationParams& params);
/// config/osm_localization.yaml (localisation from OSM alone).
void readParams(const ParamReader& reader, OsmLocalizerParams& params);

}  // namespace osm_graph_slam
