#pragma once
// Radius outlier removal on a hash grid: the same points as pcl::RadiusOutlierRemoval (a point
// stays when at least min_neighbors others lie within radius, border included), no KD-tree.
// The cell is the radius, so every neighbour is in the 27 cells around a point; the count stops
// once it reaches min_neighbors, which in a downsampled scan is usually inside the own cell.
#include <cstdint>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// Per point of cloud: 1 when >= min_neighbors others lie within radius. num_threads: 0 = all.
std::vector<uint8_t> radiusInlierMask(const PointCloud& cloud, double radius, int min_neighbors,
                                      int num_threads = 0);

/// The points radiusInlierMask keeps, in input order (header kept).
PointCloudPtr radiusOutlierRemovalGrid(const PointCloud& cloud, double radius, int min_neighbors,
                                       int num_threads = 0);

}  // namespace osm_graph_slam
