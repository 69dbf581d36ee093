#pragma once
// Tree-trunk and pole landmarks from one LiDAR keyframe cloud (sensor or base frame, z up):
// the ground is removed with a local-minimum grid, the points of a trunk band above the ground
// are clustered in 2D, and clusters that are thin and fill the band vertically (a vertical
// cylinder: trunks, poles; not bushes, crowns or walls) become landmarks with a centre, a radius
// and a confidence.
#include <Eigen/Core>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct LandmarkExtractionParams {
  double min_range = 1.5;   ///< [m] returns on the vehicle itself are ignored
  double max_range = 40.0;  ///< [m] the seed's sensing range r; trunks farther get too few points
  double sensor_height = 1.73;  ///< [m] cloud origin above the ground (HDL-64E on a car)
  double ground_cell = 1.5;  ///< [m] ground = lowest point of the 3x3 cells around (gentle terrain)
  /// Trunk band above the ground [m]: above the undergrowth, below the crowns.
  double band_min = 0.8;
  double band_max = 2.6;
  double cluster_cell = 0.2;  ///< [m] 2D occupancy cell; 8-connected cells form a cluster
  int min_points = 5;
  double max_radius = 0.7;   ///< [m] thicker clusters are not trunks/poles (bushes, walls)
  double min_radius = 0.03;  ///< [m]
  /// Fraction of the band's 0.2 m height slices that must hold points: a cylinder fills the
  /// band, a bush or a crown reaches into it only partly.
  double min_vertical_coverage = 0.7;
  /// [m] height of those slices: about the cloud's vertical point spacing (raw scans: 0.2; a
  /// voxel-filtered cloud: its leaf size, else one point per voxel looks like a gappy cylinder).
  double slice_height = 0.2;
  /// Highest beam elevation of the sensor [deg] (HDL-64E +2; OS1-64 +16.6): close to the
  /// sensor the top of the band is above the highest beam, so coverage counts the visible part.
  double max_elevation_deg = 2.0;
  /// [m] the sensor above the cloud's origin (0: sensor frame; KITTI base_link: 0.80), where the
  /// beams of max_elevation_deg start.
  double sensor_above_origin = 0.0;
  /// Landmarks with a lower confidence are dropped (see Landmark::confidence).
  double min_confidence = 0.3;
};

struct Landmark {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  ///< [m] in the cloud's frame
  double radius = 0.0;                               ///< [m]
  /// In [0, 1]: vertical coverage of the band x saturation of the point count (1 - exp(-n/15)).
  double confidence = 0.0;
  int points = 0;
  double vertical_coverage = 0.0;
};

/// Landmarks of a cloud (non-finite points are skipped; an empty cloud gives none).
std::vector<Landmark> extractLandmarks(const PointCloud& cloud,
                                       const LandmarkExtractionParams& params);

/// Just the centres.
std::vector<Eigen::Vector2d> landmarkCenters(const std::vector<Landmark>& landmarks);

}  // namespace osm_graph_slam
