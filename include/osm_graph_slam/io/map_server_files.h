#pragma once
// An occupancy grid as map_server loads it (wiki.ros.org/map_server, "Map format"): a binary PGM
// (P5) whose row 0 is the top of the map (the highest y), occupied cells black (0), free white
// (254), unknown grey (205), and a YAML file naming the image with resolution, origin [x, y, yaw]
// of the lower-left pixel, occupied_thresh 0.65, free_thresh 0.196 and negate 0. These are
// map_saver's own values: read back in trinary mode each pixel gives the cell's class again.
#include <string>

#include "osm_graph_slam/cloud/occupancy_grid.h"

namespace osm_graph_slam {

/// The class map_server gives a cell of `value` (-1 unknown, else 0..100) read back from the pair.
enum class MapServerCell { kFree, kOccupied, kUnknown };
MapServerCell mapServerClass(int8_t value);

std::string mapServerPgm(const OccupancyGridImage& grid);
std::string mapServerYaml(const OccupancyGridImage& grid, const std::string& image_name);

}  // namespace osm_graph_slam
