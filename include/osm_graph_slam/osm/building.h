#pragma once
// OSM map elements as the core sees them (ENU metres after EnuConverter, lat/lon as read).
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

struct GeoPoint {
  double lat = 0.0;  ///< degrees
  double lon = 0.0;  ///< degrees
};

using OsmTags = std::map<std::string, std::string>;

struct Building {
  int64_t id = 0;  ///< OSM way id; multipolygon relations are stored as -relation id
  /// Outer ring index of a multipolygon relation (0 for ways); (id, part) is unique.
  int part = 0;
  /// The way's OSM version (0: unknown, e.g. a simulated or GeoJSON building): an editor uploads
  /// a corrected way against the version it was read at.
  int version = 0;
  OsmTags tags;
  std::vector<GeoPoint> outline_geo;  ///< closed ring, first vertex not repeated
  Polygon2 outline_enu;               ///< same ring in ENU [m] (filled by EnuConverter)
  /// Reference corner (the outline vertex with the lowest x, ART-SLAM §5.1.5), heading 0.
  Pose2 reference_pose;
  std::vector<LineSegment2> segments;  ///< walls: one segment per outline edge, ENU
};

struct Road {
  int64_t id = 0;
  std::string highway;  ///< value of the highway=* tag
  OsmTags tags;
  std::vector<GeoPoint> nodes_geo;
  std::vector<Eigen::Vector2d> nodes_enu;  ///< filled by EnuConverter
};

}  // namespace osm_graph_slam
