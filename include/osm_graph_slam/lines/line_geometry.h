#pragma once
// Line-segment geometry of the line matcher (OSM thesis §3.3.1, §3.3.4): segment distances with
// and without coverage, angular and virtual edges, polygon overlap, visibility. Plain polygon
// geometry (distances, segments, transforms) is in common/polygon2d.h.
#include <utility>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"
#include "osm_graph_slam/common/polygon2d.h"

namespace osm_graph_slam {

/// Line-to-line distance without coverage (§3.3.4, fig. 3.8a): mean distance of the two source
/// endpoints to the target segment (projection when inside it, else its nearest endpoint).
double segmentDistanceNoCoverage(const LineSegment2& source, const LineSegment2& target);

/// Line-to-line distance with coverage (fig. 3.8b): the endpoints (of both segments) whose
/// projection falls inside the other segment are averaged by their distance to the other line;
/// coverage is the length of the source covered by the target [m]. Without overlap the distance
/// falls back to the one without coverage and the coverage is 0.
struct CoverageDistance {
  double distance = 0.0;
  double coverage = 0.0;
};
CoverageDistance segmentDistanceWithCoverage(const LineSegment2& source,
                                             const LineSegment2& target);

/// An edge (§3.3.1): the intersection of two segments' lines with the two rays from the corner
/// along the segments. Ordered so that ray2 is counter-clockwise of ray1 by `opening` in (0, pi).
struct LineEdge {
  Eigen::Vector2d corner = Eigen::Vector2d::Zero();
  double ray1 = 0.0, ray2 = 0.0;  ///< ray directions [rad]
  double opening = 0.0;           ///< CCW angle from ray1 to ray2 [rad]
  double arm1 = 0.0, arm2 = 0.0;  ///< corner to the far end of each segment along its ray [m]
  int seg1 = -1, seg2 = -1;       ///< segment indices of ray1 and ray2
  bool virtual_edge = false;      ///< true: the segments do not share an endpoint
};

struct EdgeParams {
  double min_angle_deg = 30.0;        ///< lines closer to parallel than this form no edge
  double endpoint_tolerance = 1.0;    ///< corner this close to both segments: angular edge [m]
  double max_virtual_distance = 6.0;  ///< corner at most this far beyond each segment [m]
};

/// Angular and virtual edges of a segment set. A corner inside a segment (T or X junction) gives
/// an edge for each side of that segment.
std::vector<LineEdge> extractEdges(const std::vector<LineSegment2>& segments, const EdgeParams& p);

/// Area of the intersection of two simple polygons [m^2] (either orientation).
double polygonOverlapArea(const Polygon2& a, const Polygon2& b);

/// Pairs (i < j, sorted) of polygons whose bounding boxes, grown by margin [m], intersect: the
/// candidates for overlap and contact tests. A sweep along x, so a city of thousands of
/// buildings costs about n log n, not n^2. Empty polygons pair with nothing.
std::vector<std::pair<size_t, size_t>> nearbyPolygonPairs(
    const std::vector<const Polygon2*>& polygons, double margin);

/// Indices (as in polygonSegments) of the walls of a building outline that a sensor at
/// `viewpoint` can see: the wall faces it (the viewpoint is on its outer side), some of it lies
/// within max_range, and at least one of three points along it is not hidden behind another
/// wall of the outline or of the occluders. Shared walls of touching buildings are hidden.
std::vector<size_t> visibleWalls(const Polygon2& outline, const Eigen::Vector2d& viewpoint,
                                 double max_range, const std::vector<const Polygon2*>& occluders);

}  // namespace osm_graph_slam
