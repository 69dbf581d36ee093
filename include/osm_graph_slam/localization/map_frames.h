#pragma once
// Frames around a saved map: a drive's own ENU frame (anchored at its first fix) carried into the
// map's ENU frame, and the map's ground height under a 2D position (rviz /initialpose and
// --initial-pose x,y,yaw give no z; the filter does not search in z).
#include <Eigen/Geometry>

#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/osm/enu_converter.h"

namespace osm_graph_slam {

/// Rigid map between two ENU frames anchored at different fixes (p_to = T * p_from), from the
/// geodetic conversion of the origin and three unit axes 100 m long.
Eigen::Isometry3d enuToEnu(const EnuConverter& from, const EnuConverter& to);

/// The height of the map keyframe nearest to position (2D); 0 for a map without keyframes.
double mapHeightAt(const MapPackage& map, const Eigen::Vector3d& position);

/// A pose in the map from x, y and yaw (z from mapHeightAt, no roll or pitch).
Eigen::Isometry3d mapPoseFromXyYaw(const MapPackage& map, double x, double y, double yaw);

}  // namespace osm_graph_slam
