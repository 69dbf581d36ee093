#pragma once
// Forest and park worlds for landmark place recognition (issue 24): no buildings, a network of
// trails with loops (the route planner drives them like roads), tree trunks with crowns placed as
// in the GeoSLAM thesis §4.5.2 (Bridson Poisson-disc sampling with a minimum distance, each tree
// then moved by zero-mean Gaussian noise; Table 4.4: dense 4 m / 2 m, intermediate 7 m / 3 m,
// sparse 9 m / 3.5 m = 42,011 / 13,770 / 8,419 trees per km^2), undergrowth clutter (bushes,
// saplings, fallen logs) and the gentle terrain of the GroundModel. Deterministic per seed.
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/sim/scene.h"

namespace osm_graph_slam::sim {

struct ForestParams {
  uint64_t seed = 1;
  bool park = false;          ///< park: groves and open lawns, lamp posts and benches on paths
  double size = 420.0;        ///< side of the square world [m]
  double min_distance = 7.0;  ///< Poisson-disc minimum distance between trees [m]
  double jitter_sigma = 3.0;  ///< Gaussian displacement of each tree [m]
  double trunk_radius_min = 0.10, trunk_radius_max = 0.35;  ///< [m]
  double crown_base_min = 3.5, crown_base_max = 7.0;        ///< crown bottom above the ground [m]
  double trail_spacing = 105.0;      ///< trail grid spacing [m] (4 x 4 junctions at 420 m)
  double trail_wiggle = 6.0;         ///< lateral wiggle of trail vertices [m]
  double trail_clearance = 3.0;      ///< trunks keep this from a trail centre line [m]
  double junction_clearance = 11.0;  ///< clearing around junctions (rounded corners) [m]
  double bushes_per_ha = 120.0;      ///< undergrowth spheres, 0.3-1.0 m, tops below 1.5 m
  double saplings_per_ha = 25.0;     ///< thin stems (r 2-5 cm): trunk-like clutter
  double logs_per_ha = 15.0;         ///< fallen logs (boxes on the ground)
  /// Park only: fraction of the area in groves (elsewhere lawn with a few solitary trees).
  double park_grove_fraction = 0.35;
  double park_lamp_spacing = 30.0;  ///< lamp posts along the paths [m]
};

/// Presets: "sparse", "intermediate", "dense" (thesis Table 4.4), "park" (intermediate
/// spacing in groves only, lamp posts). False for an unknown name.
bool forestPreset(const std::string& name, ForestParams& params);

/// Poisson-disc samples (Bridson) in [0, w] x [0, h] with a minimum distance; deterministic.
std::vector<Eigen::Vector2d> poissonDiscSamples(double w, double h, double min_distance,
                                                uint64_t seed, int attempts = 30);

/// The forest (or park) scene: trails in scene.roads (type "track"/"path"), trees, clutter.
Scene forestScene(const ForestParams& params, const GroundModel& ground = GroundModel());

/// Trunk centres and radii of a forest scene's trees (label kTree cylinders thicker than
/// saplings): the landmark ground truth.
struct TrunkTruth {
  Eigen::Vector2d center;
  double radius;
};
std::vector<TrunkTruth> forestTrunks(const Scene& scene, double min_radius = 0.08);

}  // namespace osm_graph_slam::sim
