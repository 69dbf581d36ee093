#pragma once
// ROS messages built from dataset records (KITTI raw/odometry, MulRan, the simulator's output).
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/time.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/io/kitti_raw.h"

namespace osm_graph_slam {

ros::Time toRosTime(StampNs stamp_ns);

/// Rotation R = Rz(yaw) Ry(pitch) Rx(roll) (the OXTS convention).
Eigen::Quaterniond quaternionFromRpy(double roll, double pitch, double yaw);

/// PointCloud2 with float32 fields x y z intensity (point_step 16) whose data is a byte copy of
/// xyzi (4 floats per point): the values of a .bin scan arrive bit-exactly.
sensor_msgs::PointCloud2 makeXyziCloud(const std::vector<float>& xyzi, const std::string& frame_id,
                                       const ros::Time& stamp);

/// GPS fix of an OXTS record; covariance from pos_accuracy (horizontal) and twice that vertically.
/// A record without a fix (OxtsRecord::hasGnssFix) gives STATUS_NO_FIX, covariance unknown.
sensor_msgs::NavSatFix makeNavSatFix(const OxtsRecord& oxts, const std::string& frame_id,
                                     const ros::Time& stamp);

/// IMU message of an OXTS record: orientation from roll/pitch/yaw (ENU), angular velocity
/// (wf, wl, wu) and linear acceleration incl. gravity (af, al, au), in the IMU frame.
sensor_msgs::Imu makeImuFromOxts(const OxtsRecord& oxts, const std::string& frame_id,
                                 const ros::Time& stamp);

/// The pose of child in parent as a TF message.
geometry_msgs::TransformStamped makeTransform(const Eigen::Isometry3d& parent_T_child,
                                              const std::string& parent, const std::string& child,
                                              const ros::Time& stamp);

/// Odometry of child_frame in frame_id; twist (body frame) optional.
nav_msgs::Odometry makeOdometry(const Eigen::Isometry3d& pose, const std::string& frame_id,
                                const std::string& child_frame_id, const ros::Time& stamp,
                                const Eigen::Vector3d& linear_velocity = Eigen::Vector3d::Zero(),
                                const Eigen::Vector3d& angular_velocity = Eigen::Vector3d::Zero());

/// mono8 image from a row-major 8-bit buffer with the given row step in bytes.
sensor_msgs::Image makeMono8Image(int rows, int cols, const uint8_t* data, size_t step,
                                  const std::string& frame_id, const ros::Time& stamp);

}  // namespace osm_graph_slam
