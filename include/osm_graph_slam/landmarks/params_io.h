#pragma once
// Reading the landmark stage's parameters from any ParamReader with the keys of
// config/landmarks.yaml: extraction under "extraction/", the hierarchy under "hierarchy/", the
// matching under "matching/", the place recognizer's own at the top level.
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/landmarks/landmark_extraction.h"
#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"

namespace osm_graph_slam {

void readParams(const ParamReader& reader, LandmarkExtractionParams& params);
void readParams(const ParamReader& reader, GeometricHierarchyParams& params);
void readParams(const ParamReader& reader, HierarchyMatchParams& params);
void readParams(const ParamReader& reader, LandmarkPlaceRecognitionParams& params);

}  // namespace osm_graph_slam
