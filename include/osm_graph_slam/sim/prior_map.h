#pragma once
// The prior map the SLAM system gets: every true building perturbed (rigid offset about its
// centroid), some removed, some phantom buildings added; plus the truth files.
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/sim/scene.h"

namespace osm_graph_slam::sim {

/// How the prior map's buildings are misplaced (see doc/simulator.md, "Prior-map error models").
enum class PriorModel {
  kIndependent,  ///< every building its own rigid offset (the original model)
  kBlocks,       ///< neighbourhoods moved together (touching buildings keep their shared nodes)
  kGlobal,       ///< the whole map shifted by one vector (and optionally rotated)
  kMixed,        ///< global + blocks + a small independent offset per building
};

/// "independent", "blocks", "global", "mixed"; false for any other name.
bool parsePriorModel(const std::string& name, PriorModel& model);
const char* priorModelName(PriorModel model);

struct PriorPerturbationParams {
  uint64_t seed = 1;
  PriorModel model = PriorModel::kIndependent;
  double translation_sigma = 1.0;   ///< [m] per axis, per building (independent)
  double rotation_sigma_deg = 2.0;  ///< [deg] per building about its centroid (independent)
  double removal_fraction = 0.05;   ///< of the true buildings
  double phantom_fraction = 0.03;   ///< phantom buildings added, relative to the true count

  /// blocks / mixed: groups are the connected components of touching buildings (outlines closer
  /// than block_touch_distance), merged per grid cell of block_size (the cell of the component's
  /// vertex mean; <= 0: no grid, components alone). One rigid offset per group, rotation about
  /// the group's vertex mean.
  double block_size = 80.0;               ///< [m]
  double block_touch_distance = 0.05;     ///< [m]
  double block_translation_sigma = 1.0;   ///< [m] per axis
  double block_rotation_sigma_deg = 1.0;  ///< [deg]
  double block_residual_sigma = 0.0;      ///< [m] per building on top (0: shared nodes kept)
  double block_residual_rotation_sigma_deg = 0.0;  ///< [deg] per building on top

  /// global / mixed: every vertex moved by one vector of random direction and a magnitude
  /// uniform in [min, max], rotated by N(0, sigma) about the vertex mean of all buildings.
  double global_offset_min = 1.0;          ///< [m]
  double global_offset_max = 3.0;          ///< [m]
  double global_rotation_sigma_deg = 0.0;  ///< [deg]

  /// mixed: the independent part per building (on top of global and block offsets).
  double mixed_translation_sigma = 0.3;   ///< [m] per axis
  double mixed_rotation_sigma_deg = 0.5;  ///< [deg]
};

struct PriorBuilding {
  enum class Status { kPerturbed, kRemoved, kPhantom } status = Status::kPerturbed;
  int64_t osm_id = 0;
  Polygon2 outline;  ///< as published in prior.osm (ENU); empty when removed
  OsmTags tags;
  /// prior = R(dtheta) (true - centroid) + centroid + (dx, dy)   (zero for phantoms)
  double dx = 0, dy = 0, dtheta = 0;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  ///< of the true outline (vertex mean)
};

/// What perturbBuildings drew for the whole map (sim_info.json).
struct PriorMapInfo {
  Eigen::Vector2d global_offset = Eigen::Vector2d::Zero();  ///< global / mixed [m]
  double global_rotation = 0.0;                             ///< [rad] about the buildings' mean
  size_t groups = 0;                                        ///< blocks / mixed
};

std::vector<PriorBuilding> perturbBuildings(const Scene& scene, const PriorPerturbationParams& p,
                                            PriorMapInfo* info = nullptr);

/// The groups of the blocks model: group index per building (parallel to
/// scene.world.buildings), numbered in order of first appearance.
std::vector<int> priorBlockGroups(const Scene& scene, const PriorPerturbationParams& p);

/// OSM XML of the published prior buildings and all roads of the scene (lat/lon via enu).
/// Building vertices at identical ENU coordinates become one node (shared nodes, as in OSM);
/// road ways get nodes of their own.
bool writePriorOsm(const std::string& path, const std::vector<PriorBuilding>& prior,
                   const Scene& scene, const EnuConverter& enu, std::string* error = nullptr);
/// osm_id,status,dx_m,dy_m,dtheta_deg,centroid_x,centroid_y (ENU of the simulation).
bool writePriorOffsetsCsv(const std::string& path, const std::vector<PriorBuilding>& prior,
                          std::string* error = nullptr);
/// True outlines as GeoJSON (lon/lat rings, properties osm_id, height_m, enu ring).
bool writeBuildingsGeoJson(const std::string& path, const Scene& scene, const EnuConverter& enu,
                           std::string* error = nullptr);

}  // namespace osm_graph_slam::sim
