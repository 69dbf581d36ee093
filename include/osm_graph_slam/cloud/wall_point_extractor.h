#pragma once
// Wall points of a keyframe (OSM thesis §3.2): drop points below the LiDAR horizon, keep points
// whose local plane is vertical, flatten to z = 0 — in this order (each step needs the previous).
#include <memory>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/logger.h"

namespace osm_graph_slam {

struct WallPointExtractorParams {
  /// Points with z below this height (cloud frame) are dropped. 0 = the sensor's horizon when the
  /// cloud frame is the sensor frame; for a base_link on the ground use the sensor height.
  double horizon_height = 0.0;
  double min_range = 2.0;  ///< horizontal range below which points are dropped (ego vehicle) [m]
  double max_range = 0.0;  ///< horizontal range above which points are dropped; 0 = no limit [m]
  /// Voxel leaf after the horizon cut; bounds the work independently of the sensor. 0 disables.
  double voxel_size = 0.25;
  int k_neighbors = 8;                 ///< neighbours of the local plane fit
  double max_normal_angle_deg = 15.0;  ///< plane normal within this angle of horizontal
  double max_neighbor_distance = 1.5;  ///< k-th neighbour farther than this: isolated, dropped
  std::string normal_backend = "nanoflann";  ///< nanoflann (ours, TBB) | pcl (NormalEstimationOMP)
  int num_threads = 0;                       ///< 0 = all hardware threads
};

struct WallPointStats {
  size_t input = 0;          ///< points given
  size_t finite = 0;         ///< after dropping NaN/Inf
  size_t above_horizon = 0;  ///< after the horizon and range cut
  size_t voxelized = 0;      ///< after the voxel grid
  size_t walls = 0;          ///< output points
  double ms = 0.0;           ///< total
  double cut_ms = 0.0;       ///< horizon and range cut
  double voxel_ms = 0.0;     ///< voxel grid
  double normal_ms = 0.0;    ///< neighbourhoods and plane test
};

class WallPointExtractor {
 public:
  /// logger: where the "bad input" warnings go (once per reason); null = stderr.
  explicit WallPointExtractor(const WallPointExtractorParams& params = {},
                              std::shared_ptr<const Logger> logger = nullptr);

  /// Returns the wall points flattened to z = 0 (intensity kept). Never throws; an empty or
  /// all-NaN cloud gives an empty result.
  PointCloudPtr extract(const PointCloud& cloud, WallPointStats* stats = nullptr) const;

  const WallPointExtractorParams& params() const { return params_; }

 private:
  WallPointExtractorParams params_;
  std::shared_ptr<const Logger> logger_;
};

}  // namespace osm_graph_slam
