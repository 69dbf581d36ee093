#pragma once
// Building <-> osm_graph_slam/Building(Array) messages and rviz markers.
//
// The message osm_graph_slam/Building would become the C++ type osm_graph_slam::Building, the
// name of the core struct. Include the messages through this header: it renames the message
// typedef to osm_graph_slam::BuildingMsg (BuildingArray keeps its name). Never include
// <osm_graph_slam/Building.h> directly in a file that also sees the core Building.
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/osm/enu_converter.h"

#define Building BuildingMsg
#include <osm_graph_slam/Building.h>
#include <osm_graph_slam/BuildingArray.h>
#undef Building

namespace osm_graph_slam {

BuildingMsg buildingToMsg(const Building& building);
/// enu (optional) refills outline_geo from the ENU outline.
Building buildingFromMsg(const BuildingMsg& msg, const EnuConverter* enu = nullptr);

BuildingArray buildingArrayToMsg(const std::vector<Building>& buildings,
                                 const std_msgs::Header& header,
                                 const Eigen::Vector2d& query_centre, double query_radius);
std::vector<Building> buildingsFromMsg(const BuildingArray& msg, const EnuConverter* enu = nullptr);

/// Outlines (one LINE_LIST) and reference corners (one SPHERE_LIST), preceded by DELETEALL.
visualization_msgs::MarkerArray buildingMarkers(const std::vector<Building>& buildings,
                                                const std_msgs::Header& header,
                                                const std::string& ns = "osm_buildings");

}  // namespace osm_graph_slam
