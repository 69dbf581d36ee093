#pragma once
// Building <-> osm_graph_slam/OsmBuilding(Array) messages and rviz markers. (The message is
// called OsmBuilding so that its C++ type does not clash with the core struct Building.)
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/osm/enu_converter.h"

#include <osm_graph_slam/BuildingArray.h>
#include <osm_graph_slam/OsmBuilding.h>

namespace osm_graph_slam {

OsmBuilding buildingToMsg(const Building& building);
/// enu (optional) refills outline_geo from the ENU outline.
Building buildingFromMsg(const OsmBuilding& msg, const EnuConverter* enu = nullptr);

BuildingArray buildingArrayToMsg(const std::vector<Building>& buildings,
                                 const std_msgs::Header& header,
                                 const Eigen::Vector2d& query_centre, double query_radius);
std::vector<Building> buildingsFromMsg(const BuildingArray& msg, const EnuConverter* enu = nullptr);

/// Outlines (one LINE_LIST) and reference corners (one SPHERE_LIST), preceded by DELETEALL.
visualization_msgs::MarkerArray buildingMarkers(const std::vector<Building>& buildings,
                                                const std_msgs::Header& header,
                                                const std::string& ns = "osm_buildings");

}  // namespace osm_graph_slam
