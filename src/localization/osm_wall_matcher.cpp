#include "osm_graph_slam/localization/osm_wall_matcher.h"

#include <set>

#include "osm_graph_slam/common/polygon2d.h"
#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {

OsmWallMatcher::OsmWallMatcher(std::vector<Building> buildings,
                               const WallPointExtractorParams& walls,
                               const LineSegmentExtractorParams& segments,
                               const LineMatcherParams& matcher)
    : buildings_(std::move(buildings)), walls_(walls), segments_(segments), matcher_(matcher) {}

size_t OsmWallMatcher::addBuildings(std::vector<Building> buildings) {
  std::set<int64_t> held;
  for (const Building& b : buildings_) held.insert(b.id);
  size_t added = 0;
  for (Building& b : buildings) {
    if (!held.insert(b.id).second) continue;
    buildings_.push_back(std::move(b));
    ++added;
  }
  return added;
}

std::vector<LineSegment2> OsmWallMatcher::scanWalls(const PointCloud& cloud) const {
  return segments_.extract(*walls_.extract(cloud));
}

std::vector<LineSegment2> OsmWallMatcher::wallsSeenFrom(const Eigen::Vector2d& p,
                                                        double radius) const {
  std::vector<const Building*> near;
  std::vector<const Polygon2*> occluders;
  for (const Building& b : buildings_)
    if (distanceToPolygon(p, b.outline_enu) <= radius) {
      near.push_back(&b);
      occluders.push_back(&b.outline_enu);
    }
  std::vector<LineSegment2> out;
  for (const Building* b : near)
    for (size_t w : visibleWalls(b->outline_enu, p, radius, occluders))
      if (w < b->segments.size()) out.push_back(b->segments[w]);
  return out;
}

}  // namespace osm_graph_slam
