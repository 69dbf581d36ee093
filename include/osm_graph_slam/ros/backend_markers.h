#pragma once
// rviz markers of the back-end: graph vertices and edges (coloured by type and level), original
// OSM outlines vs corrected ones, and the keyframes' wall segments in the map.
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include <vector>

#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

visualization_msgs::MarkerArray backendMarkers(const PoseGraph& graph,
                                               const std::vector<KeyframeState>& keyframes,
                                               const std::vector<BuildingState>& buildings,
                                               const std_msgs::Header& header);

}  // namespace osm_graph_slam
