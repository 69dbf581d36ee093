#pragma once
// Roll, pitch and yaw of an orientation in the OXTS / ROS convention R = Rz(yaw) Ry(pitch)
// Rx(roll): the one place the IMU adapters, the drive readers and the back-end take them from.
#include <Eigen/Geometry>

namespace osm_graph_slam {

Eigen::Vector2d rollPitchOf(const Eigen::Matrix3d& R);
double yawOf(const Eigen::Matrix3d& R);
inline Eigen::Vector2d rollPitchOf(const Eigen::Quaterniond& q) {
  return rollPitchOf(q.normalized().toRotationMatrix());
}
inline double yawOf(const Eigen::Quaterniond& q) {
  return yawOf(q.normalized().toRotationMatrix());
}
/// R = Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Matrix3d rotationFromRollPitchYaw(double roll, double pitch, double yaw);

}  // namespace osm_graph_slam
