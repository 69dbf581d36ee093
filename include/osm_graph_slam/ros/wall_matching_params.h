#pragma once
// The SLAM pipeline's wall extraction (config/line_extraction.yaml: wall, segments) and line
// matcher (config/graph_backend.yaml: line_matcher), read where a launch file loaded them: both
// localisation nodelets match scan walls with OSM walls exactly as the SLAM back-end does.
#include <string>

#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"

namespace osm_graph_slam {

struct WallMatchingParams {
  WallPointExtractorParams walls;
  LineSegmentExtractorParams segments;
  LineMatcherParams matcher;
};

/// Missing keys keep the structs' defaults. found = false when neither namespace holds any
/// parameter (the launch file did not load them): the caller should say so.
WallMatchingParams readWallMatchingParams(const std::string& line_extraction_ns,
                                          const std::string& line_matcher_ns, bool* found);

}  // namespace osm_graph_slam
