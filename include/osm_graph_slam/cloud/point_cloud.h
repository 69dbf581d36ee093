#pragma once
// The point type passed between every 3D stage.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace osm_graph_slam {

using PointT = pcl::PointXYZI;
using PointCloud = pcl::PointCloud<PointT>;
using PointCloudPtr = PointCloud::Ptr;
using PointCloudConstPtr = PointCloud::ConstPtr;

}  // namespace osm_graph_slam
