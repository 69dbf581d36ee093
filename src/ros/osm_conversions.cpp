#include "osm_graph_slam/ros/osm_conversions.h"

namespace osm_graph_slam {
namespace {

geometry_msgs::Point toPoint(const Eigen::Vector2d& v, double z = 0.0) {
  geometry_msgs::Point p;
  p.x = v.x();
  p.y = v.y();
  p.z = z;
  return p;
}

Eigen::Vector2d fromPoint(const geometry_msgs::Point& p) {
  return {p.x, p.y};
}

}  // namespace

OsmBuilding buildingToMsg(const Building& building) {
  OsmBuilding msg;
  msg.id = building.id;
  msg.outline.reserve(building.outline_enu.size());
  for (const auto& v : building.outline_enu) msg.outline.push_back(toPoint(v));
  msg.reference_pose.x = building.reference_pose.x;
  msg.reference_pose.y = building.reference_pose.y;
  msg.reference_pose.theta = building.reference_pose.theta;
  msg.segments.reserve(building.segments.size());
  for (const auto& s : building.segments) {
    osm_graph_slam::LineSegment seg;
    seg.start = toPoint(s.start);
    seg.end = toPoint(s.end);
    seg.support = s.support;
    msg.segments.push_back(seg);
  }
  for (const auto& [key, value] : building.tags) {
    msg.tag_keys.push_back(key);
    msg.tag_values.push_back(value);
  }
  return msg;
}

Building buildingFromMsg(const OsmBuilding& msg, const EnuConverter* enu) {
  Building b;
  b.id = msg.id;
  for (const auto& p : msg.outline) b.outline_enu.push_back(fromPoint(p));
  b.reference_pose = Pose2(msg.reference_pose.x, msg.reference_pose.y, msg.reference_pose.theta);
  for (const auto& s : msg.segments) {
    b.segments.emplace_back(fromPoint(s.start), fromPoint(s.end), s.support);
  }
  const size_t n = std::min(msg.tag_keys.size(), msg.tag_values.size());
  for (size_t i = 0; i < n; ++i) b.tags[msg.tag_keys[i]] = msg.tag_values[i];
  if (enu) {
    for (const auto& v : b.outline_enu) b.outline_geo.push_back(enu->toGeoPoint(v));
  }
  return b;
}

BuildingArray buildingArrayToMsg(const std::vector<Building>& buildings,
                                 const std_msgs::Header& header,
                                 const Eigen::Vector2d& query_centre, double query_radius) {
  BuildingArray msg;
  msg.header = header;
  msg.query_center = toPoint(query_centre);
  msg.query_radius = query_radius;
  msg.buildings.reserve(buildings.size());
  for (const Building& b : buildings) msg.buildings.push_back(buildingToMsg(b));
  return msg;
}

std::vector<Building> buildingsFromMsg(const BuildingArray& msg, const EnuConverter* enu) {
  std::vector<Building> out;
  out.reserve(msg.buildings.size());
  for (const auto& b : msg.buildings) out.push_back(buildingFromMsg(b, enu));
  return out;
}

visualization_msgs::MarkerArray buildingMarkers(const std::vector<Building>& buildings,
                                                const std_msgs::Header& header,
                                                const std::string& ns) {
  visualization_msgs::MarkerArray array;
  visualization_msgs::Marker clear;
  clear.header = header;
  clear.ns = ns;
  clear.action = visualization_msgs::Marker::DELETEALL;
  array.markers.push_back(clear);

  visualization_msgs::Marker outlines;
  outlines.header = header;
  outlines.ns = ns;
  outlines.id = 0;
  outlines.type = visualization_msgs::Marker::LINE_LIST;
  outlines.action = visualization_msgs::Marker::ADD;
  outlines.pose.orientation.w = 1.0;
  outlines.scale.x = 0.3;
  outlines.color.r = 0.95f;
  outlines.color.g = 0.55f;
  outlines.color.b = 0.1f;
  outlines.color.a = 1.0f;
  visualization_msgs::Marker corners = outlines;
  corners.id = 1;
  corners.type = visualization_msgs::Marker::SPHERE_LIST;
  corners.scale.x = corners.scale.y = corners.scale.z = 1.0;
  corners.color.r = 0.1f;
  corners.color.g = 0.4f;
  corners.color.b = 0.95f;
  for (const Building& b : buildings) {
    const size_t n = b.outline_enu.size();
    for (size_t i = 0; i < n && n >= 2; ++i) {
      outlines.points.push_back(toPoint(b.outline_enu[i]));
      outlines.points.push_back(toPoint(b.outline_enu[(i + 1) % n]));
    }
    corners.points.push_back(toPoint(b.reference_pose.translation()));
  }
  if (!outlines.points.empty()) {
    array.markers.push_back(outlines);
    array.markers.push_back(corners);
  }
  return array;
}

}  // namespace osm_graph_slam
