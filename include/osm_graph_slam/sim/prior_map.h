#pragma once
// The prior map the SLAM system gets: every true building perturbed (rigid offset about its
// centroid), some removed, some phantom buildings added; plus the truth files.
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/sim/scene.h"

namespace osm_graph_slam::sim {

struct PriorPerturbationParams {
  uint64_t seed = 1;
  double translation_sigma = 1.0;   ///< [m] per axis
  double rotation_sigma_deg = 2.0;  ///< [deg]
  double removal_fraction = 0.05;   ///< of the true buildings
  double phantom_fraction = 0.03;   ///< phantom buildings added, relative to the true count
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

std::vector<PriorBuilding> perturbBuildings(const Scene& scene, const PriorPerturbationParams& p);

/// OSM XML of the published prior buildings and all roads of the scene (lat/lon via enu).
bool writePriorOsm(const std::string& path, const std::vector<PriorBuilding>& prior,
                   const Scene& scene, const EnuConverter& enu, std::string* error = nullptr);
/// osm_id,status,dx_m,dy_m,dtheta_deg,centroid_x,centroid_y (ENU of the simulation).
bool writePriorOffsetsCsv(const std::string& path, const std::vector<PriorBuilding>& prior,
                          std::string* error = nullptr);
/// True outlines as GeoJSON (lon/lat rings, properties osm_id, height_m, enu ring).
bool writeBuildingsGeoJson(const std::string& path, const Scene& scene, const EnuConverter& enu,
                           std::string* error = nullptr);

}  // namespace osm_graph_slam::sim
