#pragma once
// Parameters of the 2-D occupancy grid (cloud/occupancy_grid.h), apart from the grid so that
// backend_params.h can hold them without pulling PCL into every back-end user.
#include <string>

#include "osm_graph_slam/common/param_declaration.h"

namespace osm_graph_slam {

struct OccupancyGridParams {
  bool enabled = true;      ///< graph_backend publishes slam/grid_map, save_map writes map.pgm
  double resolution = 0.2;  ///< [m] cell size
  /// Obstacle band above the local ground [m]: lower points are ground (free), higher ones
  /// overhangs a vehicle passes under (ignored).
  double min_height = 0.3;
  double max_height = 2.0;
  double min_range = 1.0;   ///< [m] horizontal; closer returns are the vehicle itself
  double max_range = 40.0;  ///< [m] horizontal; farther returns are ignored
  /// One free-space ray per azimuth sector of this width, to its nearest obstacle or, with
  /// none, to its farthest ground return: O(sectors x range) per keyframe instead of O(points).
  double azimuth_step_deg = 0.5;
  double hit_probability = 0.7;   ///< per keyframe that sees an obstacle in a cell
  double miss_probability = 0.4;  ///< per keyframe whose rays cross a cell
  /// Bounds of a cell's probability when it is read (clamped then, not while summing, so that a
  /// keyframe's contribution can be taken out exactly when the graph moves it).
  double min_probability = 0.12;
  double max_probability = 0.97;
  /// Local ground: the keyframe's floor plane (floor_detection) or, without one, this low
  /// percentile of the heights within 15 m; per ground_cell the lowest point moves it by at most
  /// ground_tolerance (slopes, kerbs).
  double ground_percentile = 0.1;
  double ground_cell = 2.0;       ///< [m]
  double ground_tolerance = 0.3;  ///< [m]
  /// A keyframe whose pose changed by more than this is re-rendered (its old contribution taken
  /// out, the new one added); smaller moves do not change cells.
  double move_translation = 0.05;  ///< [m]
  double move_rotation = 0.002;    ///< [rad]

  template <class V>
  void visit(V& v) {
    v("grid_enabled", enabled, "publish slam/grid_map (nav_msgs/OccupancyGrid), save map.pgm");
    v("grid_resolution", resolution, "[m] occupancy grid cell size");
    v("grid_min_height", min_height, "[m] obstacle band above the local ground: from ...");
    v("grid_max_height", max_height, "[m] ... to (higher: overhangs, ignored)");
    v("grid_min_range", min_range, "[m] horizontal; closer returns are the vehicle");
    v("grid_max_range", max_range, "[m] horizontal; farther returns are ignored");
    v("grid_azimuth_step_deg", azimuth_step_deg,
      "[deg] one free-space ray per sector: to its nearest obstacle, else its farthest ground");
    v("grid_hit_probability", hit_probability, "per keyframe seeing an obstacle in a cell");
    v("grid_miss_probability", miss_probability, "per keyframe whose rays cross a cell");
    v("grid_min_probability", min_probability, "a cell's probability is clamped to [min, ...");
    v("grid_max_probability", max_probability, "... max] when read");
    v("grid_ground_percentile", ground_percentile,
      "without a floor plane: ground = this percentile of the heights within 15 m");
    v("grid_ground_cell", ground_cell, "[m] cells of the local ground correction");
    v("grid_ground_tolerance", ground_tolerance,
      "[m] the lowest point of a ground cell moves the ground by at most this");
    v("grid_move_translation", move_translation,
      "[m] a keyframe moved more by an optimisation is re-rendered");
    v("grid_move_rotation", move_rotation, "[rad] or turned more");
  }
};

/// Empty when the parameters make a grid; otherwise what is wrong, naming the key.
std::string occupancyGridParamsError(const OccupancyGridParams& params);

}  // namespace osm_graph_slam
