#pragma once
// Buildings that share a wall in the map (row houses, blocks). Touching outlines are the rule in
// OSM city blocks; a building seen through one facade is then still placed along its street by
// the neighbours it touches (doc/backend.md "Shared walls").
#include <Eigen/Core>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

struct BuildingContactParams {
  /// [m] facing walls this far apart (gap or overlap) in the prior count as one shared wall. Real
  /// OSM neighbours share nodes; a prior that misplaces each building on its own (the simulator,
  /// 1 m per axis) needs a few metres (config/sim.yaml: 2.5).
  double max_distance = 0.5;
  double max_angle_deg = 8.0;  ///< facing walls antiparallel within this
  /// The walls must face each other over this fraction of the shorter one, or over min_length.
  double min_shared_fraction = 0.5;
  double min_shared_length = 2.0;  ///< [m]
  double min_wall_length = 1.0;    ///< [m] shorter walls are ignored
};

struct BuildingContact {
  size_t a = 0, b = 0;  ///< indices into the outlines, a < b
  /// Ends of the shared span on a's wall (same frame as the outlines).
  Eigen::Vector2d a_ends[2];
  Eigen::Vector2d b_point;   ///< a point of b's wall
  Eigen::Vector2d b_normal;  ///< b's outward unit normal of that wall
  double distance = 0.0;     ///< [m] gap (> 0) or overlap (< 0) between the two walls
  double shared_length = 0.0;
};

/// At most one contact per pair: the facing wall pair with the longest shared span.
std::vector<BuildingContact> findBuildingContacts(const std::vector<Polygon2>& outlines,
                                                  const BuildingContactParams& params);

}  // namespace osm_graph_slam
