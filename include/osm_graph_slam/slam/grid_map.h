#pragma once
// The occupancy grid of a back-end's keyframes (cloud/occupancy_grid.h): kept in step with the
// graph by the graph_backend nodelet, built whole by save_map when nobody kept one.
#include <vector>

#include "osm_graph_slam/cloud/occupancy_grid.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

struct GridMapUpdate {
  size_t inserted = 0;            ///< keyframes new to the grid
  size_t moved = 0;               ///< keyframes re-rendered at a new pose
  std::vector<double> insert_ms;  ///< per inserted keyframe
  double move_ms = 0.0;           ///< the re-rendering of the moved ones, together
};

/// Inserts the keyframes the grid lacks (those with a cloud) at their map poses, with their floor
/// planes; re-renders known ones the graph moved. Keyframe clouds are in base_link, whose origin
/// is taken as the sensor's: its horizontal offset only shifts where free rays start.
GridMapUpdate updateGridMap(OccupancyGrid& grid, const std::vector<KeyframeState>& keyframes);

}  // namespace osm_graph_slam
