#pragma once
// Building the simulated world: from an OSM extract (buildings extruded, roads = highway ways) or
// a procedural city from a seed; then clutter along the roads (trees, parked cars, fences and low
// walls, poles, moving objects) kept clear of buildings, roads and the planned route.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/sim/route.h"
#include "osm_graph_slam/sim/world.h"

namespace osm_graph_slam {
struct OsmData;
class EnuConverter;
}  // namespace osm_graph_slam

namespace osm_graph_slam::sim {

struct Scene {
  World world;
  std::vector<OsmTags> building_tags;  ///< parallel to world.buildings (as read / generated)
  std::vector<Polyline2> roads;        ///< drivable road centre lines, ENU
  std::vector<int64_t> road_ids;
  std::vector<std::string> road_types;  ///< highway=* value
  std::vector<Polyline2>
      other_roads;  ///< non-drivable highway ways (footways, ...), kept for prior.osm
  std::vector<int64_t> other_road_ids;
  std::vector<std::string> other_road_types;
  /// The procedural city's downtown district (empty box: none).
  Eigen::AlignedBox2d downtown;
};

/// A downtown district (issue 52: urban canyons for the GNSS model): the city's central blocks,
/// each split into four by narrow streets and built up with towers. Off by default.
struct DowntownParams {
  bool enabled = false;
  int blocks_x = 3, blocks_y = 2;  ///< central blocks of the grid it replaces
  double setback = 6.0;            ///< street centre line to facade [m]: 12 m between facades
  double min_height = 20.0, max_height = 80.0;  ///< towers [m]
  double lot_min = 12.0, lot_max = 25.0;        ///< tower frontage along the street [m]
  double gap_probability = 0.3;                 ///< a passage (1-3 m) between two towers
};

struct CityParams {
  uint64_t seed = 1;
  int blocks_x = 7, blocks_y = 6;
  double block_min = 70.0, block_max = 110.0;  ///< street spacing [m]
  double setback = 9.5;                        ///< street centre line to lot [m]
  double park_probability = 0.1;
  double round_probability = 0.06;
  double l_shape_probability = 0.25;
  /// "city" (default), or a forest/park world (sim/forest_world.h; issue 24): "forest" with
  /// forest_density sparse|intermediate|dense, or "park".
  std::string world = "city";
  std::string forest_density = "intermediate";
  /// Added after the city is drawn, from a random stream of its own: the buildings outside the
  /// district are those of the city without it (same seed), byte for byte.
  DowntownParams downtown;
};

struct ClutterParams {
  uint64_t seed = 1;
  double tree_spacing = 11.0, tree_probability = 0.55, tree_offset = 7.0;
  double pole_spacing = 32.0, pole_offset = 5.6;
  double car_slot = 6.5, car_probability = 0.35, car_offset = 4.2;
  double fence_probability = 0.2, fence_offset = 8.3;  ///< per 25 m of road side
  double fence_max_height = 1.5;
  int moving_cars = 4, moving_pedestrians = 4;
  double junction_clearance = 12.0;  ///< no clutter this close to road junctions [m]
  double route_clearance = 2.4;      ///< clutter footprint keeps this from the route [m]
};

/// Height of an OSM building: height=*, else building:levels * 3 m + 1 m, else a deterministic
/// 8-25 m from the id and seed.
double buildingHeight(const OsmTags& tags, int64_t id, uint64_t seed);

/// True if highway=value is a road a car drives on.
bool isDrivableHighway(const std::string& value);

/// Buildings and roads from an OSM extract (already read). Every building with a valid outline
/// becomes a SimBuilding (osm id kept). Heights per buildingHeight().
Scene sceneFromOsm(const OsmData& osm, const EnuConverter& enu, uint64_t seed,
                   const GroundModel& ground = GroundModel());

/// A procedural city: a street grid and blocks of buildings (rectangles, L-shapes, a few round).
Scene proceduralCity(const CityParams& params, const GroundModel& ground = GroundModel());

/// Adds static clutter and moving objects along scene.roads, clear of buildings, roads, junctions
/// and the route (may be empty). Call before world.finalize().
void addClutter(Scene& scene, const ClutterParams& params, const Trajectory* route = nullptr);

/// Fills base/top heights of scene buildings from the ground model (called by the builders).
void settleBuildings(World& world);

}  // namespace osm_graph_slam::sim
