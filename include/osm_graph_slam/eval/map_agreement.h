#pragma once
// Measures of a run without ground truth (a real drive): how well the accumulated wall points
// agree with the building outlines (the OSM prior's and the corrected ones), how far buildings
// moved that no keyframe saw, and how sharp the accumulated map is (a prior that bends the
// trajectory blurs it).
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

/// A keyframe's cloud (base_link) at its optimised map pose.
using PosedCloud = std::pair<Eigen::Isometry3d, PointCloudConstPtr>;

struct WallAgreementOptions {
  /// Wall points: base_link z in [min_z, max_z]. Default: 2-6 m above the road for KITTI's
  /// base_link (the OXTS unit, 0.93 m above the road), above cars and below most eaves.
  double min_z = 1.07, max_z = 5.07;
  double max_distance = 3.0;  ///< [m] points farther from every outline are not walls of one
  double voxel = 0.2;         ///< [m] of the accumulated wall points (each place counts once)
  size_t min_points = 50;     ///< a building with fewer points counts as unobserved
  /// The back-end's OSM datum (x, y, yaw: the extract's common offset it estimated), if any:
  /// the unobserved buildings' shift is also reported after it (what they moved on their own).
  std::optional<Eigen::Vector3d> datum;
};

struct BuildingAgreement {
  int64_t id = 0;
  int part = 0;
  size_t points = 0;
  double prior_median = 0, prior_p90 = 0;          ///< point-to-outline [m]
  double corrected_median = 0, corrected_p90 = 0;  ///< [m]
  double shift = 0;  ///< [m] largest vertex displacement, corrected vs prior
};

/// A roof on open sides (isRoofOnly): no walls to measure; what lies under it instead.
struct RoofAgreement {
  int64_t id = 0;
  int part = 0;
  size_t inside_prior = 0, inside_corrected = 0;  ///< wall-band points inside the outline
  double shift = 0;                               ///< [m] as BuildingAgreement::shift
};

struct WallAgreement {
  std::vector<BuildingAgreement> observed;  ///< buildings with >= min_points wall points
  /// Left out of the wall measure and of `unobserved`: the points near a shelter's outline are
  /// those of the platform, fence or tram beside it (real drive 0005), not its walls.
  std::vector<RoofAgreement> roof_only;
  size_t points = 0;  ///< wall points assigned to observed buildings
  /// Medians over the observed buildings of their per-building medians / 90th percentiles.
  double prior_median = 0, corrected_median = 0, prior_p90 = 0, corrected_p90 = 0;
  size_t unobserved = 0;
  double max_unobserved_shift = 0;  ///< [m]
  int64_t max_unobserved_shift_id = 0;
  /// [m] the largest unobserved shift left after the datum's (options.datum given; else -1)
  double max_unobserved_shift_after_datum = -1;
};

/// prior and corrected: the same buildings (matched by id and part), ENU filled.
WallAgreement evaluateWallAgreement(const std::vector<PosedCloud>& keyframes,
                                    const std::vector<Building>& prior,
                                    const std::vector<Building>& corrected,
                                    const WallAgreementOptions& options = {});

struct MapSharpness {
  size_t points = 0;               ///< map points with enough neighbours
  double mean_plane_variance = 0;  ///< [m^2] mean smallest covariance eigenvalue of neighbourhoods
};

/// Mean plane variance of the accumulated map (voxel-downsampled), neighbourhoods of `radius`.
MapSharpness evaluateMapSharpness(const std::vector<PosedCloud>& keyframes, double voxel = 0.1,
                                  double radius = 0.3, size_t min_neighbours = 8);

}  // namespace osm_graph_slam
