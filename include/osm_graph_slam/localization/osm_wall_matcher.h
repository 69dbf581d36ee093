#pragma once
// A scan's wall segments against the OSM building walls a sensor could see from a point: what
// both localisers need from OSM (OSM-SLAM §5.1). OsmLocalizer tracks with it; Localizer searches
// with it for its pose when neither the keyframes nor their side views answer (issue 21, 3b).
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

class OsmWallMatcher {
 public:
  /// buildings: outlines and wall segments in the frame the poses are wanted in.
  OsmWallMatcher(std::vector<Building> buildings, const WallPointExtractorParams& walls = {},
                 const LineSegmentExtractorParams& segments = {},
                 const LineMatcherParams& matcher = {});

  /// More buildings; ids already held are skipped. Returns how many were added.
  size_t addBuildings(std::vector<Building> buildings);
  size_t numBuildings() const { return buildings_.size(); }

  /// The wall segments of a prefiltered scan (base_link).
  std::vector<LineSegment2> scanWalls(const PointCloud& cloud) const;
  /// The walls a sensor at p can see (facing it, within radius, not hidden by other buildings):
  /// matching against every wall around would count the unseen ones as unmatched.
  std::vector<LineSegment2> wallsSeenFrom(const Eigen::Vector2d& p, double radius) const;

  const LineMatcher& matcher() const { return matcher_; }

 private:
  std::vector<Building> buildings_;
  WallPointExtractor walls_;
  LineSegmentExtractor segments_;
  LineMatcher matcher_;
};

}  // namespace osm_graph_slam
