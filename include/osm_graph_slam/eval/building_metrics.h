#pragma once
// How far corrected buildings are from the true ones, and whether outlines overlap.
#include <vector>

#include "osm_graph_slam/osm/building_set.h"  // findOverlappingBuildings

namespace osm_graph_slam {

struct BuildingErrors {
  size_t matched = 0;              ///< buildings present (by id) in both sets
  size_t vertex_mismatch = 0;      ///< matched by id but with different vertex counts (skipped)
  double mean_corner_error = 0.0;  ///< [m] reference corner (true lowest-x vertex) distance
  double max_corner_error = 0.0;   ///< [m]
  double mean_heading_error_deg = 0.0;  ///< |rotation| of the best 2D fit estimate -> truth
  double mean_vertex_error = 0.0;       ///< [m] over all corresponding vertices
  /// The set's common offset: |mean reference-corner displacement| [m]. A map can only be as
  /// close to the truth as its absolute references (fixes, the map's own mean offset) put it.
  double common_offset = 0.0;
  /// Mean corner error once the common offset is removed [m]: the map's shape, what scans and
  /// building priors decide (doc/matrix.md, "S_shp").
  double mean_corner_error_shape = 0.0;
};

/// Compares buildings by OSM id. Vertices correspond by order (a prior is a perturbed copy of
/// the truth), so the reference corner is compared as the same physical corner.
BuildingErrors evaluateBuildings(const std::vector<Building>& estimate,
                                 const std::vector<Building>& truth);

}  // namespace osm_graph_slam
