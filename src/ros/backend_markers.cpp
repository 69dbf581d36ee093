#include "osm_graph_slam/ros/backend_markers.h"

#include <map>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {
namespace {

using visualization_msgs::Marker;

std_msgs::ColorRGBA rgba(float r, float g, float b, float a = 1.0f) {
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

geometry_msgs::Point point(double x, double y, double z) {
  geometry_msgs::Point p;
  p.x = x;
  p.y = y;
  p.z = z;
  return p;
}

Marker makeMarker(const std_msgs::Header& header, const std::string& ns, int type, double scale,
                  const std_msgs::ColorRGBA& color) {
  Marker m;
  m.header = header;
  m.ns = ns;
  m.id = 0;
  m.type = type;
  m.action = Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = scale;
  m.color = color;
  return m;
}

/// Position of a vertex for drawing (SE2/XY vertices at z = 0).
bool vertexPosition(const PoseGraph& graph, int id, geometry_msgs::Point* p) {
  if (auto se3 = graph.vertexSE3(id)) {
    *p = point(se3->translation().x(), se3->translation().y(), se3->translation().z());
    return true;
  }
  if (auto se2 = graph.vertexSE2(id)) {
    *p = point(se2->x, se2->y, 0.0);
    return true;
  }
  if (auto xy = graph.vertexPointXY(id)) {
    *p = point(xy->x(), xy->y(), 0.0);
    return true;
  }
  return false;
}

void addOutlines(Marker& m, const Polygon2& outline, double z) {
  for (size_t i = 0; i < outline.size(); ++i) {
    const auto& a = outline[i];
    const auto& b = outline[(i + 1) % outline.size()];
    m.points.push_back(point(a.x(), a.y(), z));
    m.points.push_back(point(b.x(), b.y(), z));
  }
}

}  // namespace

visualization_msgs::MarkerArray backendMarkers(const PoseGraph& graph,
                                               const std::vector<KeyframeState>& keyframes,
                                               const std::vector<BuildingState>& buildings,
                                               const std_msgs::Header& header) {
  visualization_msgs::MarkerArray out;
  Marker clear;
  clear.header = header;
  clear.action = Marker::DELETEALL;
  out.markers.push_back(clear);

  Marker robots = makeMarker(header, "robot_vertices", Marker::SPHERE_LIST, 0.6, rgba(1, 1, 0));
  for (const auto& kf : keyframes) {
    const auto& t = kf.map_pose.translation();
    robots.points.push_back(point(t.x(), t.y(), t.z()));
  }
  out.markers.push_back(robots);

  // Edges by kind: odometry/loops (level 0), global priors (level 0, drawn as short spikes),
  // robot↔building (level 1), building↔building (level 2).
  Marker odometry =
      makeMarker(header, "edges_level0_robot", Marker::LINE_LIST, 0.08, rgba(0, 0.8, 1));
  Marker priors =
      makeMarker(header, "edges_level0_map_prior", Marker::LINE_LIST, 0.05, rgba(1, 0, 1));
  Marker mapping = makeMarker(header, "edges_level1_robot_building", Marker::LINE_LIST, 0.02,
                              rgba(1, 0.6, 0, 0.5));
  Marker overlap =
      makeMarker(header, "edges_level2_building_building", Marker::LINE_LIST, 0.15, rgba(1, 0, 0));
  // Shared walls: a post at each end of the wall span the two buildings keep in common.
  Marker shared =
      makeMarker(header, "edges_level1_shared_wall", Marker::LINE_LIST, 0.3, rgba(1, 1, 1));
  for (const auto& [id, e] : graph.edges()) {
    geometry_msgs::Point a, b;
    if (e.type == EdgeType::kSE2PointOnLine) {
      if (const auto owner = graph.vertexSE2(e.vertices[0])) {
        const Eigen::Vector2d end = owner->transform(e.measurement.head<2>());
        shared.points.push_back(point(end.x(), end.y(), 0.0));
        shared.points.push_back(point(end.x(), end.y(), 4.0));
      }
      continue;
    }
    if (!vertexPosition(graph, e.vertices[0], &a)) continue;
    if (e.num_vertices == 1) {
      if (e.type == EdgeType::kPriorSE2) continue;  // every building has one: not worth a line
      priors.points.push_back(a);
      priors.points.push_back(point(a.x, a.y, a.z + 2.0));
      continue;
    }
    if (!vertexPosition(graph, e.vertices[1], &b)) continue;
    Marker& m = e.level >= 2 ? overlap : e.level == 1 ? mapping : odometry;
    m.points.push_back(a);
    m.points.push_back(b);
  }
  for (Marker* m : {&odometry, &priors, &mapping, &overlap, &shared})
    if (!m->points.empty()) out.markers.push_back(*m);

  Marker original =
      makeMarker(header, "buildings_osm", Marker::LINE_LIST, 0.15, rgba(0.6, 0.6, 0.6));
  Marker corrected =
      makeMarker(header, "buildings_corrected", Marker::LINE_LIST, 0.25, rgba(0.1, 0.9, 0.2));
  for (const auto& b : buildings) {
    addOutlines(original, b.prior.outline_enu, 0.0);
    addOutlines(corrected, transformPolygon(b.local_outline, b.pose), 0.1);
  }
  if (!original.points.empty()) {
    out.markers.push_back(original);
    out.markers.push_back(corrected);
  }

  Marker segments =
      makeMarker(header, "keyframe_segments", Marker::LINE_LIST, 0.1, rgba(0.2, 0.4, 1));
  for (const auto& kf : keyframes) {
    const Pose2 pose = planarPose(kf.map_pose);
    for (const auto& s : kf.segments) {
      const LineSegment2 m = s.transformed(pose);
      segments.points.push_back(point(m.start.x(), m.start.y(), 0.2));
      segments.points.push_back(point(m.end.x(), m.end.y(), 0.2));
    }
  }
  if (!segments.points.empty()) out.markers.push_back(segments);
  return out;
}

}  // namespace osm_graph_slam
