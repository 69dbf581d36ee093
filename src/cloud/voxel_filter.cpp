#include "osm_graph_slam/cloud/voxel_filter.h"

#include <pcl/filters/approximate_voxel_grid.h>
#include <pcl/filters/voxel_grid.h>

namespace osm_graph_slam {

PointCloudPtr voxelDownsample(const PointCloudConstPtr& cloud, double leaf, bool exact) {
  PointCloudPtr out = std::make_shared<PointCloud>();
  const float l = static_cast<float>(leaf);
  if (exact) {
    pcl::VoxelGrid<PointT> grid;
    grid.setLeafSize(l, l, l);
    grid.setInputCloud(cloud);
    grid.filter(*out);
  } else {
    pcl::ApproximateVoxelGrid<PointT> grid;
    grid.setLeafSize(l, l, l);
    grid.setInputCloud(cloud);
    grid.filter(*out);
  }
  out->header = cloud->header;
  return out;
}

}  // namespace osm_graph_slam
