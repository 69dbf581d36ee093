#pragma once
// A small ray-cast world of extruded boxes and poles on flat ground, with a rotating multi-beam
// LiDAR. It gives loop-detection tests and the loop benchmark scans with real occlusion and
// noise without depending on the full project simulator (sim/).
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct SyntheticBox {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double yaw = 0.0;
  Eigen::Vector2d half_size = Eigen::Vector2d::Ones();
  double height = 5.0;
};

struct SyntheticPole {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius = 0.2;
  double height = 6.0;
};

struct SyntheticWorld {
  std::vector<SyntheticBox> boxes;
  std::vector<SyntheticPole> poles;
};

struct SyntheticLidarParams {
  int beams = 32;
  int columns = 720;
  double min_elevation_deg = -25.0;
  double max_elevation_deg = 15.0;
  double max_range = 80.0;
  double sensor_height = 1.73;  ///< above the ground plane z = 0
  double noise_stddev = 0.02;   ///< [m] along the ray
};

/// Scan in the sensor frame of a sensor at (pose_xy, yaw) and sensor_height; points beyond
/// max_range are dropped. seed makes the noise reproducible.
PointCloudPtr simulateSyntheticScan(const SyntheticWorld& world, const Eigen::Vector2d& position,
                                    double yaw, const SyntheticLidarParams& params, uint32_t seed);

/// A town for loop tests: a rectangular loop of streets of width ~16 m. The street along y = 0
/// (x in [0, length_x]) is lined with identical, evenly spaced buildings and poles (a
/// repetitive facade street); the others have random buildings, poles and parked cars.
SyntheticWorld makeLoopTown(double length_x, double length_y, double facade_period, uint32_t seed);

/// Points along the closed rectangle (0,0) -> (length_x,0) -> (length_x,length_y) -> (0,length_y)
/// -> (0,0), then again along the first street for extra_distance; one pose every spacing metres
/// starting at offset. Returns (x, y, yaw) of the vehicle; lateral_offset shifts it to the left.
std::vector<Eigen::Vector3d> loopTownRoute(double length_x, double length_y, double extra_distance,
                                           double spacing, double offset, double lateral_offset);

}  // namespace osm_graph_slam
