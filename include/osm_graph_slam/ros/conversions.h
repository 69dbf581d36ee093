#pragma once
// Message <-> core type conversions shared by every nodelet and tool (ROS side only).
#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <nav_msgs/OccupancyGrid.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <string>

#include "osm_graph_slam/cloud/occupancy_grid.h"
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// Reads x, y, z (any numeric field type) and, if present, intensity from a PointCloud2 into a
/// PointCloud (intensity 0 when absent). The header's stamp and frame_id are copied. Returns
/// false with a reason for a message without x/y/z, a big-endian or truncated buffer.
bool fromPointCloud2(const sensor_msgs::PointCloud2& msg, PointCloud& cloud,
                     std::string* error = nullptr);

/// Writes cloud (x, y, z, intensity as float32) into msg; header.frame_id/stamp from cloud's
/// PCL header (use msg.header afterwards to override).
void toPointCloud2(const PointCloud& cloud, sensor_msgs::PointCloud2& msg);

geometry_msgs::Pose toPoseMsg(const Eigen::Isometry3d& pose);
geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3d& pose);
/// The orientation is normalised; a zero quaternion becomes the identity rotation.
Eigen::Isometry3d fromPoseMsg(const geometry_msgs::Pose& pose);
Eigen::Isometry3d fromTransformMsg(const geometry_msgs::Transform& transform);

/// x, y, z, roll, pitch, yaw (extrinsic X-Y-Z, i.e. R = Rz(yaw) Ry(pitch) Rx(roll)).
/// The fix's horizontal standard deviation [m] from its covariance (mean of the east and north
/// variances), or 0 when the covariance is unknown or not a usable number.
double navSatFixStd(const sensor_msgs::NavSatFix& fix);

/// The grid in the message's layout (row-major, row 0 at the lowest y, origin its corner).
void toOccupancyGridMsg(const OccupancyGridImage& grid, const std_msgs::Header& header,
                        nav_msgs::OccupancyGrid& msg);

Eigen::Isometry3d fromXyzRpy(double x, double y, double z, double roll, double pitch, double yaw);

}  // namespace osm_graph_slam
