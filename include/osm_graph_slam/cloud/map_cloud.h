#pragma once
// One cloud from many posed clouds (a map from keyframes), reduced to voxel centroids.
#include <Eigen/Geometry>
#include <vector>

#include "osm_graph_slam/cloud/cloud_store.h"
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// A cloud in its own frame and that frame's pose in the common one.
struct PosedCloud {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  StoredCloud cloud;  ///< loaded one at a time; none (or unreadable): skipped
};

/// The clouds moved into the common frame, merged and reduced to one point (the centroid) per
/// voxel; resolution <= 0 keeps every point. A hash grid instead of pcl::VoxelGrid: the latter's
/// 32-bit voxel index overflows on city-sized maps at fine resolutions.
PointCloudPtr mergeClouds(const std::vector<PosedCloud>& clouds, double resolution);

}  // namespace osm_graph_slam
