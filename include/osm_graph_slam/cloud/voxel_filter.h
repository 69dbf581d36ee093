#pragma once
// Voxel-grid downsampling, the one place it is written (PCL's filters stay in the .cpp).
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// exact: pcl::VoxelGrid (centroid per voxel); else pcl::ApproximateVoxelGrid (faster, hashed).
/// The output keeps the input's header.
PointCloudPtr voxelDownsample(const PointCloudConstPtr& cloud, double leaf, bool exact = false);

/// pcl::VoxelGrid's result (centroid of x, y, z and intensity of the finite points of each voxel,
/// in its voxel order; sums in another order, so equal within float rounding) from one pass over
/// a hash grid instead of PCL's sort and per-field copies: ~2.5x faster on a 20k-point scan.
/// Empty header; beyond +-2^20 voxels from the origin it runs PCL's filter.
PointCloudPtr voxelCentroids(const PointCloud& cloud, double leaf);

}  // namespace osm_graph_slam
