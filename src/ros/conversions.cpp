#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/common/attitude.h"

#include <cmath>

#include <pcl_conversions/pcl_conversions.h>
#include <sensor_msgs/point_field_conversion.h>

#include <cstring>
#include <limits>

namespace osm_graph_slam {
namespace {

const sensor_msgs::PointField* findField(const sensor_msgs::PointCloud2& msg,
                                         const std::string& name) {
  for (const auto& f : msg.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

float readField(const uint8_t* data, uint8_t datatype) {
  return sensor_msgs::readPointCloud2BufferValue<float>(data, datatype);
}

size_t fieldSize(uint8_t datatype) {
  using sensor_msgs::PointField;
  switch (datatype) {
    case PointField::INT8:
    case PointField::UINT8:
      return 1;
    case PointField::INT16:
    case PointField::UINT16:
      return 2;
    case PointField::INT32:
    case PointField::UINT32:
    case PointField::FLOAT32:
      return 4;
    case PointField::FLOAT64:
      return 8;
  }
  return 0;
}

bool fail(std::string* error, const std::string& reason) {
  if (error) *error = reason;
  return false;
}

}  // namespace

bool fromPointCloud2(const sensor_msgs::PointCloud2& msg, PointCloud& cloud, std::string* error) {
  cloud.clear();
  cloud.header = pcl_conversions::toPCL(msg.header);
  const sensor_msgs::PointField* fx = findField(msg, "x");
  const sensor_msgs::PointField* fy = findField(msg, "y");
  const sensor_msgs::PointField* fz = findField(msg, "z");
  const sensor_msgs::PointField* fi = findField(msg, "intensity");
  if (!fx || !fy || !fz) return fail(error, "PointCloud2 has no x/y/z fields");
  if (msg.is_bigendian) return fail(error, "big-endian PointCloud2 is not supported");
  for (const auto* f : {fx, fy, fz, fi}) {
    if (f && (fieldSize(f->datatype) == 0 || f->offset + fieldSize(f->datatype) > msg.point_step)) {
      return fail(error, "PointCloud2 field '" + f->name + "' has a bad type or offset");
    }
  }
  const size_t points = size_t(msg.width) * msg.height;
  if (points == 0) return true;
  if (msg.row_step < size_t(msg.width) * msg.point_step ||
      msg.data.size() < size_t(msg.row_step) * msg.height) {
    return fail(error, "PointCloud2 data is shorter than width x height x point_step");
  }
  cloud.reserve(points);
  for (uint32_t row = 0; row < msg.height; ++row) {
    const uint8_t* row_data = msg.data.data() + size_t(row) * msg.row_step;
    for (uint32_t col = 0; col < msg.width; ++col) {
      const uint8_t* p = row_data + size_t(col) * msg.point_step;
      PointT q;
      q.x = readField(p + fx->offset, fx->datatype);
      q.y = readField(p + fy->offset, fy->datatype);
      q.z = readField(p + fz->offset, fz->datatype);
      q.intensity = fi ? readField(p + fi->offset, fi->datatype) : 0.0f;
      cloud.push_back(q);
    }
  }
  cloud.width = static_cast<uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = msg.is_dense;
  return true;
}

void toPointCloud2(const PointCloud& cloud, sensor_msgs::PointCloud2& msg) {
  pcl::toROSMsg(cloud, msg);
}

geometry_msgs::Pose toPoseMsg(const Eigen::Isometry3d& pose) {
  geometry_msgs::Pose msg;
  msg.position.x = pose.translation().x();
  msg.position.y = pose.translation().y();
  msg.position.z = pose.translation().z();
  const Eigen::Quaterniond q(pose.linear());
  msg.orientation.w = q.w();
  msg.orientation.x = q.x();
  msg.orientation.y = q.y();
  msg.orientation.z = q.z();
  return msg;
}

geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3d& pose) {
  const geometry_msgs::Pose p = toPoseMsg(pose);
  geometry_msgs::Transform msg;
  msg.translation.x = p.position.x;
  msg.translation.y = p.position.y;
  msg.translation.z = p.position.z;
  msg.rotation = p.orientation;
  return msg;
}

namespace {

Eigen::Isometry3d makeIsometry(double x, double y, double z, double qw, double qx, double qy,
                               double qz) {
  Eigen::Quaterniond q(qw, qx, qy, qz);
  if (q.norm() < 1e-12) q = Eigen::Quaterniond::Identity();
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = q.normalized().toRotationMatrix();
  out.translation() << x, y, z;
  return out;
}

}  // namespace

Eigen::Isometry3d fromPoseMsg(const geometry_msgs::Pose& p) {
  return makeIsometry(p.position.x, p.position.y, p.position.z, p.orientation.w, p.orientation.x,
                      p.orientation.y, p.orientation.z);
}

Eigen::Isometry3d fromTransformMsg(const geometry_msgs::Transform& t) {
  return makeIsometry(t.translation.x, t.translation.y, t.translation.z, t.rotation.w, t.rotation.x,
                      t.rotation.y, t.rotation.z);
}

Eigen::Isometry3d fromXyzRpy(double x, double y, double z, double roll, double pitch, double yaw) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = rotationFromRollPitchYaw(roll, pitch, yaw);
  out.translation() << x, y, z;
  return out;
}

void toOccupancyGridMsg(const OccupancyGridImage& grid, const std_msgs::Header& header,
                        nav_msgs::OccupancyGrid& msg) {
  msg.header = header;
  msg.info.map_load_time = header.stamp;
  msg.info.resolution = static_cast<float>(grid.resolution);
  msg.info.width = static_cast<uint32_t>(grid.width);
  msg.info.height = static_cast<uint32_t>(grid.height);
  msg.info.origin =
      toPoseMsg(Eigen::Isometry3d(Eigen::Translation3d(grid.origin.x(), grid.origin.y(), 0.0)));
  msg.data = grid.cells;
}

double navSatFixStd(const sensor_msgs::NavSatFix& fix) {
  if (fix.position_covariance_type == sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN) return 0.0;
  const double var = 0.5 * (fix.position_covariance[0] + fix.position_covariance[4]);
  return std::isfinite(var) && var > 0.0 ? std::sqrt(var) : 0.0;
}

}  // namespace osm_graph_slam
