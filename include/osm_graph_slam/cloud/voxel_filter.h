#pragma once
// Voxel-grid downsampling, the one place it is written (PCL's filters stay in the .cpp).
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// exact: pcl::VoxelGrid (centroid per voxel); else pcl::ApproximateVoxelGrid (faster, hashed).
/// The output keeps the input's header.
PointCloudPtr voxelDownsample(const PointCloudConstPtr& cloud, double leaf, bool exact = false);

}  // namespace osm_graph_slam
