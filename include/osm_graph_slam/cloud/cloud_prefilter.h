#pragma once
// Pre-filterer of raw LiDAR scans (ART-SLAM thesis §3.1.3): invalid-point removal, range crop,
// sensor -> base_link transform, voxel-grid downsampling and outlier removal run on the eight
// octants of the cloud in parallel.
#include <Eigen/Geometry>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct CloudPrefilterParams {
  bool remove_invalid = true;  ///< drop points with NaN/Inf coordinates

  bool use_range_crop = true;  ///< keep points with min_range <= |p| <= max_range (sensor frame)
  double min_range = 2.0;      ///< [m] removes the ego vehicle and near-field noise
  double max_range = 100.0;    ///< [m]

  bool use_voxel_grid = true;
  std::string voxel_method = "approximate";  ///< approximate (ApproximateVoxelGrid) | exact
  double voxel_leaf_size = 0.5;              ///< [m]

  bool use_outlier_removal = true;
  std::string outlier_method = "radius";  ///< radius | statistical
  double radius_search = 1.0;             ///< [m] radius outlier removal
  int radius_min_neighbors = 2;           ///< neighbours (besides the point) needed within radius
  /// Radius removal: grid (ours, a hash grid with early exit; the same points as PCL, ~10x
  /// faster) | pcl (pcl::RadiusOutlierRemoval, whole cloud or octants: the baseline).
  std::string radius_backend = "grid";
  int statistical_mean_k = 20;      ///< neighbours for statistical outlier removal
  double statistical_stddev = 1.0;  ///< threshold: mean + stddev_mul * sigma

  bool parallel_octants = true;  ///< split into 8 octants and filter them in parallel
  /// Points within this distance of an octant's border are added to it as (unfiltered) support so
  /// that border points see the same neighbours as in the whole cloud [m]. 0 = radius_search for
  /// the radius method, 2 m for the statistical one.
  double octant_margin = 0.0;
  int num_threads = 0;  ///< 0 = all hardware threads

  /// sensor -> base_link (p_base = sensor_to_base * p_sensor), applied after the range crop.
  Eigen::Isometry3d sensor_to_base = Eigen::Isometry3d::Identity();
};

struct CloudPrefilterStats {
  size_t input_points = 0;
  size_t after_invalid = 0;
  size_t after_crop = 0;
  size_t after_voxel = 0;
  size_t output_points = 0;
  double time_invalid_crop_ms = 0.0;
  double time_voxel_ms = 0.0;
  double time_outlier_ms = 0.0;
  double time_total_ms = 0.0;
};

struct CloudPrefilterResult {
  PointCloudPtr cloud;  ///< never null; empty when nothing valid was left
  bool ok = false;      ///< false: the output is empty, reason says why
  std::string reason;
  CloudPrefilterStats stats;
};

class CloudPrefilter {
 public:
  explicit CloudPrefilter(const CloudPrefilterParams& params = {});

  const CloudPrefilterParams& params() const { return params_; }
  void setSensorToBase(const Eigen::Isometry3d& sensor_to_base);

  /// Runs every enabled step. Never throws on bad input: empty, all-invalid or fully cropped
  /// clouds give an empty result with ok = false and a reason.
  CloudPrefilterResult filter(const PointCloud& input) const;

  /// The outlier-removal step alone (exposed for the octant benchmark and tests).
  PointCloudPtr removeOutliers(const PointCloudConstPtr& cloud, bool parallel_octants) const;

 private:
  PointCloudPtr removeOutliersWhole(const PointCloudConstPtr& cloud) const;
  PointCloudPtr removeOutliersOctants(const PointCloudConstPtr& cloud) const;
  /// Hash-grid radius removal; octant_order: the points in the order removeOutliersOctants gives.
  PointCloudPtr removeOutliersGrid(const PointCloudConstPtr& cloud, bool octant_order) const;
  PointCloudPtr voxelize(const PointCloudConstPtr& cloud) const;

  CloudPrefilterParams params_;
};

}  // namespace osm_graph_slam
