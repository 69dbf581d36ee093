#pragma once
// Radius outlier removal on a hash grid: the same points as pcl::RadiusOutlierRemoval (a point
// stays when at least min_neighbors others lie within radius, border included), no KD-tree.
// The cell is the radius, so every neighbour is in the 27 cells around a point; the count stops
// once it reaches min_neighbors, which in a downsampled scan is usually inside the own cell.
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// Points of cloud with >= min_neighbors others within radius, in input order (header kept).
/// num_threads: 0 = all hardware threads.
PointCloudPtr radiusOutlierRemovalGrid(const PointCloud& cloud, double radius, int min_neighbors,
                                       int num_threads = 0);

}  // namespace osm_graph_slam
