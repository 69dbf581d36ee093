#pragma once
// The procedural city's downtown district (private to scene.cpp): narrow mid-block streets and
// towers of 20-80 m in the central blocks, so that the canyon GNSS model meets real canyons.
#include <vector>

#include "osm_graph_slam/sim/scene.h"

namespace osm_graph_slam::sim {

/// Rebuilds the central blocks of a procedural city whose street lines are at xs (north-south
/// roads, scene.roads[0 .. xs.size()-1]) and ys (east-west roads, the next ys.size()): removes
/// their buildings, splits each block by a street in each direction (with junction vertices in
/// the roads they meet) and fills every quarter block with towers. Sets scene.downtown. Call
/// before settleBuildings.
void addDowntown(Scene& scene, const DowntownParams& params, uint64_t seed,
                 const std::vector<double>& xs, const std::vector<double>& ys);

}  // namespace osm_graph_slam::sim
