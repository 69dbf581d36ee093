#pragma once
// A small LiDAR simulator for the line stage's tests and benchmark: extruded building outlines
// (rectangles, L-shapes, courtyards) ray-cast by rings of beams, with range noise, ground,
// trees, poles and scattered clutter. (The full urban drive simulator lives in sim/.)
#include <cstdint>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

struct SimBuilding {
  Polygon2 outline;                  ///< map frame
  std::vector<Polygon2> courtyards;  ///< inner rings (map frame)
  double height = 12.0;              ///< above ground [m]
};

struct WallScanParams {
  int rings = 16;
  double min_elevation_deg = -10.0;
  double max_elevation_deg = 10.0;
  int beams_per_ring = 1800;
  double max_range = 80.0;
  double sensor_height = 1.73;  ///< sensor above ground; the cloud's z = 0 is the sensor
  double range_noise = 0.02;    ///< sigma [m]
  int trees = 8;                ///< blobs of canopy points near the sensor
  int poles = 6;
  int scattered_points = 300;  ///< uniform clutter above the ground
  uint32_t seed = 1;
};

/// The scan of a sensor at `sensor_pose` (map frame), in the sensor frame.
PointCloudPtr simulateWallScan(const std::vector<SimBuilding>& buildings, const Pose2& sensor_pose,
                               const WallScanParams& params);

/// Every wall (outline and courtyard rings) as map-frame segments.
std::vector<LineSegment2> buildingWalls(const std::vector<SimBuilding>& buildings);
std::vector<LineSegment2> buildingWalls(const SimBuilding& building);

/// n buildings along both sides of a street on the x axis (|y| >= 7 m): rectangles, L-shapes and
/// one courtyard building, slightly rotated, none overlapping.
std::vector<SimBuilding> makeStreetScene(int n, uint32_t seed);

SimBuilding rectangleBuilding(double x0, double y0, double w, double d, double yaw = 0.0);
SimBuilding lShapeBuilding(double x0, double y0, double w, double d, double notch_w, double notch_d,
                           double yaw = 0.0);
SimBuilding courtyardBuilding(double x0, double y0, double w, double d, double wall_thickness,
                              double yaw = 0.0);

}  // namespace osm_graph_slam
