#pragma once
// Plain 2D polygon geometry, the one home for it (building outlines in osm/, the simulator's
// scene, the line matcher): point-to-segment and point-to-outline distances, inside tests,
// outlines as segments, rigid transforms, signed area.
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

/// Distance of point p to the segment s (to its nearest point).
double pointSegmentDistance(const Eigen::Vector2d& p, const LineSegment2& s);

/// Whether p is inside the closed ring (even-odd rule; points on an edge may go either way).
bool pointInPolygon(const Eigen::Vector2d& p, const Polygon2& polygon);

/// Distance from p to the nearest edge of a closed polygon (0 only on an edge, not inside).
double distanceToPolygon(const Eigen::Vector2d& p, const Polygon2& polygon);

/// The closed outline of a polygon as segments.
std::vector<LineSegment2> polygonSegments(const Polygon2& polygon);

Polygon2 transformPolygon(const Polygon2& polygon, const Pose2& T);

/// Signed area [m^2]: positive for a counter-clockwise ring (outside is then to the right).
double polygonSignedArea(const Polygon2& polygon);

}  // namespace osm_graph_slam
