#pragma once
// Reading the cloud stage's parameters from any ParamReader (ROS parameter server or YAML file).
// A missing key keeps the struct's default; keys are those of config/prefiltering.yaml and the
// "wall/" block of config/line_extraction.yaml (the caller passes a PrefixedParamReader).
#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/cloud/floor_detector.h"
#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/common/param_reader.h"

namespace osm_graph_slam {

/// Every field except sensor_to_base (a transform the nodelet takes from TF or ~sensor_to_base).
void readParams(const ParamReader& reader, CloudPrefilterParams& params);
void readParams(const ParamReader& reader, WallPointExtractorParams& params);
/// Keys of config/floor_detection.yaml.
void readParams(const ParamReader& reader, FloorDetectorParams& params);

}  // namespace osm_graph_slam
