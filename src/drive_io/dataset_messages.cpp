#include "osm_graph_slam/drive_io/dataset_messages.h"
#include "osm_graph_slam/common/attitude.h"

#include <sensor_msgs/PointField.h>
#include <sensor_msgs/image_encodings.h>

#include <cstring>

namespace osm_graph_slam {

ros::Time toRosTime(StampNs stamp_ns) {
  ros::Time t;
  t.fromNSec(static_cast<uint64_t>(stamp_ns));
  return t;
}

Eigen::Quaterniond quaternionFromRpy(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(rotationFromRollPitchYaw(roll, pitch, yaw));
}

sensor_msgs::PointCloud2 makeXyziCloud(const std::vector<float>& xyzi, const std::string& frame_id,
                                       const ros::Time& stamp) {
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = stamp;
  const char* names[] = {"x", "y", "z", "intensity"};
  for (int i = 0; i < 4; ++i) {
    sensor_msgs::PointField f;
    f.name = names[i];
    f.offset = 4 * i;
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    msg.fields.push_back(f);
  }
  const size_t n = xyzi.size() / 4;
  msg.height = 1;
  msg.width = static_cast<uint32_t>(n);
  msg.is_bigendian = false;
  msg.point_step = 16;
  msg.row_step = static_cast<uint32_t>(16 * n);
  msg.is_dense = false;
  msg.data.resize(16 * n);
  if (n) std::memcpy(msg.data.data(), xyzi.data(), 16 * n);
  return msg;
}

sensor_msgs::NavSatFix makeNavSatFix(const OxtsRecord& oxts, const std::string& frame_id,
                                     const ros::Time& stamp) {
  sensor_msgs::NavSatFix msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = stamp;
  msg.status.status = sensor_msgs::NavSatStatus::STATUS_FIX;
  msg.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS;
  msg.latitude = oxts.lat;
  msg.longitude = oxts.lon;
  msg.altitude = oxts.alt;
  if (!oxts.hasGnssFix()) {  // an outage: the record's position is no fix
    msg.status.status = sensor_msgs::NavSatStatus::STATUS_NO_FIX;
    msg.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN;
    return msg;
  }
  const double h = oxts.pos_accuracy > 0.0 ? oxts.pos_accuracy * oxts.pos_accuracy : 1.0;
  msg.position_covariance = {h, 0, 0, 0, h, 0, 0, 0, 4.0 * h};
  msg.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_DIAGONAL_KNOWN;
  return msg;
}

sensor_msgs::Imu makeImuFromOxts(const OxtsRecord& oxts, const std::string& frame_id,
                                 const ros::Time& stamp) {
  sensor_msgs::Imu msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = stamp;
  const Eigen::Quaterniond q = quaternionFromRpy(oxts.roll, oxts.pitch, oxts.yaw);
  msg.orientation.x = q.x();
  msg.orientation.y = q.y();
  msg.orientation.z = q.z();
  msg.orientation.w = q.w();
  msg.angular_velocity.x = oxts.wf;
  msg.angular_velocity.y = oxts.wl;
  msg.angular_velocity.z = oxts.wu;
  msg.linear_acceleration.x = oxts.af;
  msg.linear_acceleration.y = oxts.al;
  msg.linear_acceleration.z = oxts.au;
  // OXTS RT3003 specification: 0.03 deg roll/pitch, 0.1 deg heading, 0.01 deg/s, 0.01 m/s^2.
  const double rp = std::pow(0.03 * M_PI / 180.0, 2), yaw = std::pow(0.1 * M_PI / 180.0, 2);
  msg.orientation_covariance = {rp, 0, 0, 0, rp, 0, 0, 0, yaw};
  const double w = std::pow(0.01 * M_PI / 180.0, 2), a = 1e-4;
  msg.angular_velocity_covariance = {w, 0, 0, 0, w, 0, 0, 0, w};
  msg.linear_acceleration_covariance = {a, 0, 0, 0, a, 0, 0, 0, a};
  return msg;
}

geometry_msgs::TransformStamped makeTransform(const Eigen::Isometry3d& parent_T_child,
                                              const std::string& parent, const std::string& child,
                                              const ros::Time& stamp) {
  geometry_msgs::TransformStamped msg;
  msg.header.frame_id = parent;
  msg.header.stamp = stamp;
  msg.child_frame_id = child;
  const Eigen::Vector3d t = parent_T_child.translation();
  const Eigen::Quaterniond q(parent_T_child.linear());
  msg.transform.translation.x = t.x();
  msg.transform.translation.y = t.y();
  msg.transform.translation.z = t.z();
  msg.transform.rotation.x = q.x();
  msg.transform.rotation.y = q.y();
  msg.transform.rotation.z = q.z();
  msg.transform.rotation.w = q.w();
  return msg;
}

nav_msgs::Odometry makeOdometry(const Eigen::Isometry3d& pose, const std::string& frame_id,
                                const std::string& child_frame_id, const ros::Time& stamp,
                                const Eigen::Vector3d& linear_velocity,
                                const Eigen::Vector3d& angular_velocity) {
  nav_msgs::Odometry msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = stamp;
  msg.child_frame_id = child_frame_id;
  const Eigen::Vector3d t = pose.translation();
  const Eigen::Quaterniond q(pose.linear());
  msg.pose.pose.position.x = t.x();
  msg.pose.pose.position.y = t.y();
  msg.pose.pose.position.z = t.z();
  msg.pose.pose.orientation.x = q.x();
  msg.pose.pose.orientation.y = q.y();
  msg.pose.pose.orientation.z = q.z();
  msg.pose.pose.orientation.w = q.w();
  msg.twist.twist.linear.x = linear_velocity.x();
  msg.twist.twist.linear.y = linear_velocity.y();
  msg.twist.twist.linear.z = linear_velocity.z();
  msg.twist.twist.angular.x = angular_velocity.x();
  msg.twist.twist.angular.y = angular_velocity.y();
  msg.twist.twist.angular.z = angular_velocity.z();
  return msg;
}

sensor_msgs::Image makeMono8Image(int rows, int cols, const uint8_t* data, size_t step,
                                  const std::string& frame_id, const ros::Time& stamp) {
  sensor_msgs::Image msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = stamp;
  msg.height = static_cast<uint32_t>(rows);
  msg.width = static_cast<uint32_t>(cols);
  msg.encoding = sensor_msgs::image_encodings::MONO8;
  msg.is_bigendian = false;
  msg.step = static_cast<uint32_t>(cols);
  msg.data.resize(static_cast<size_t>(rows) * cols);
  for (int r = 0; r < rows; ++r) {
    std::memcpy(msg.data.data() + static_cast<size_t>(r) * cols, data + r * step, cols);
  }
  return msg;
}

}  // namespace osm_graph_slam
