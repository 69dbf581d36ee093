#include "osm_graph_slam/drive_io/bag_drive_reader.h"

#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <set>
#include <vector>

#include "osm_graph_slam/ros/conversions.h"

namespace osm_graph_slam {
namespace {

/// A topic as written by kitti2bag ("gps/fix") or recorded by rosbag record ("/gps/fix").
std::vector<std::string> topicVariants(const std::string& topic) {
  const std::string bare = topic.rfind('/', 0) == 0 ? topic.substr(1) : topic;
  return {bare, "/" + bare};
}

template <typename T>
const T* nearest(const std::map<int64_t, T>& by_stamp, int64_t stamp_ns, double max_dt) {
  if (by_stamp.empty()) return nullptr;
  auto after = by_stamp.lower_bound(stamp_ns);
  auto best = after;
  if (after == by_stamp.end() ||
      (after != by_stamp.begin() && stamp_ns - std::prev(after)->first < after->first - stamp_ns))
    best = std::prev(after);
  if (std::abs(static_cast<double>(best->first - stamp_ns)) * 1e-9 > max_dt) return nullptr;
  return &best->second;
}

struct StaticEdge {
  std::string parent, child;
  Eigen::Isometry3d parent_T_child;
};

}  // namespace

struct BagDriveReader::Impl {
  BagDriveTopics topics;
  rosbag::Bag bag;
  std::unique_ptr<rosbag::View> clouds;
  rosbag::View::iterator cloud_it;
  size_t num_clouds = 0;
  std::vector<BagFix> fixes;
  std::map<int64_t, Eigen::Quaterniond> imu;  ///< orientation of the IMU frame in ENU
  /// Body rates and specific force in the IMU frame (REP-145: a quantity whose covariance
  /// starts with -1 is not given and not kept).
  std::vector<std::pair<int64_t, Eigen::Vector3d>> gyro, accel;
  std::string imu_frame;
  std::map<int64_t, Eigen::Isometry3d> ground_truth;
  std::vector<StaticEdge> static_tf;

  void readSmallTopics();
  void addImuRates(const sensor_msgs::Imu& msg);
  void addStaticTf(const tf2_msgs::TFMessage& msg);
};

void BagDriveReader::Impl::addStaticTf(const tf2_msgs::TFMessage& msg) {
  for (const auto& t : msg.transforms)
    static_tf.push_back({t.header.frame_id, t.child_frame_id, fromTransformMsg(t.transform)});
}

void BagDriveReader::Impl::addImuRates(const sensor_msgs::Imu& msg) {
  const int64_t stamp = static_cast<int64_t>(msg.header.stamp.toNSec());
  const auto& w = msg.angular_velocity;
  const auto& a = msg.linear_acceleration;
  if (msg.angular_velocity_covariance[0] != -1.0)
    gyro.emplace_back(stamp, Eigen::Vector3d(w.x, w.y, w.z));
  if (msg.linear_acceleration_covariance[0] != -1.0)
    accel.emplace_back(stamp, Eigen::Vector3d(a.x, a.y, a.z));
  if (imu_frame.empty()) imu_frame = msg.header.frame_id;
}

void BagDriveReader::Impl::readSmallTopics() {
  std::vector<std::string> names;
  for (const auto* t : {&topics.gps, &topics.imu, &topics.ground_truth, &topics.tf_static})
    for (const auto& v : topicVariants(*t)) names.push_back(v);
  rosbag::View view(bag, rosbag::TopicQuery(names));
  for (const rosbag::MessageInstance& m : view) {
    if (auto fix = m.instantiate<sensor_msgs::NavSatFix>()) {
      if (fix->status.status >= sensor_msgs::NavSatStatus::STATUS_FIX &&
          std::isfinite(fix->latitude) && std::isfinite(fix->longitude) &&
          std::isfinite(fix->altitude))
        fixes.push_back({static_cast<int64_t>(fix->header.stamp.toNSec()), fix->latitude,
                         fix->longitude, fix->altitude, navSatFixStd(*fix)});
    } else if (auto imu_msg = m.instantiate<sensor_msgs::Imu>()) {
      addImuRates(*imu_msg);
      const auto& o = imu_msg->orientation;
      Eigen::Quaterniond q(o.w, o.x, o.y, o.z);
      // REP-145: orientation_covariance[0] = -1 means no orientation estimate.
      if (imu_msg->orientation_covariance[0] < 0.0 || !std::isfinite(q.norm()) || q.norm() < 1e-6)
        continue;
      imu[static_cast<int64_t>(imu_msg->header.stamp.toNSec())] = q.normalized();
      if (imu_frame.empty()) imu_frame = imu_msg->header.frame_id;
    } else if (auto odom = m.instantiate<nav_msgs::Odometry>()) {
      ground_truth[static_cast<int64_t>(odom->header.stamp.toNSec())] =
          fromPoseMsg(odom->pose.pose);
    } else if (auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
      addStaticTf(*tf);
    }
  }
}

BagDriveReader::BagDriveReader() : impl_(std::make_unique<Impl>()) {}
BagDriveReader::~BagDriveReader() = default;

bool BagDriveReader::open(const std::string& path, const BagDriveTopics& topics,
                          std::string* error) {
  impl_ = std::make_unique<Impl>();
  impl_->topics = topics;
  try {
    impl_->bag.open(path, rosbag::bagmode::Read);
    impl_->readSmallTopics();
    impl_->clouds =
        std::make_unique<rosbag::View>(impl_->bag, rosbag::TopicQuery(topicVariants(topics.cloud)));
    impl_->num_clouds = impl_->clouds->size();
    impl_->cloud_it = impl_->clouds->begin();
  } catch (const std::exception& e) {
    if (error) *error = "cannot read bag '" + path + "': " + e.what();
    return false;
  }
  if (impl_->num_clouds == 0) {
    if (error) *error = "bag '" + path + "' has no message on topic '" + topics.cloud + "'";
    return false;
  }
  return true;
}

size_t BagDriveReader::numClouds() const {
  return impl_->num_clouds;
}
size_t BagDriveReader::numImu() const {
  return impl_->imu.size();
}
size_t BagDriveReader::numGroundTruth() const {
  return impl_->ground_truth.size();
}

std::optional<BagFix> BagDriveReader::firstFix() const {
  if (impl_->fixes.empty()) return std::nullopt;
  return impl_->fixes.front();
}

const std::vector<BagFix>& BagDriveReader::fixes() const {
  return impl_->fixes;
}

std::vector<std::pair<int64_t, Eigen::Quaterniond>> BagDriveReader::orientations() const {
  // R_enu_base = R_enu_imu * R_imu_base; no static transform: the IMU is taken to be base_link.
  const std::optional<Eigen::Isometry3d> base_T_imu = baseToFrame(impl_->imu_frame);
  const Eigen::Quaterniond imu_T_base = base_T_imu
                                            ? Eigen::Quaterniond(base_T_imu->linear()).inverse()
                                            : Eigen::Quaterniond::Identity();
  std::vector<std::pair<int64_t, Eigen::Quaterniond>> out;
  out.reserve(impl_->imu.size());
  for (const auto& [stamp_ns, q] : impl_->imu)
    out.emplace_back(stamp_ns, base_T_imu ? (q * imu_T_base).normalized() : q);
  return out;
}

std::vector<BagImuReading> BagDriveReader::imuRates(bool accelerations) const {
  // Vectors turn with the mounting: v_base = R_base_imu * v_imu (the lever arm of the
  // accelerometer is ignored: centripetal terms of a few cm are below its noise).
  const std::optional<Eigen::Isometry3d> base_T_imu = baseToFrame(impl_->imu_frame);
  const Eigen::Matrix3d R =
      base_T_imu ? Eigen::Matrix3d(base_T_imu->linear()) : Eigen::Matrix3d::Identity();
  std::vector<BagImuReading> out;
  for (const auto& [stamp_ns, v] : accelerations ? impl_->accel : impl_->gyro)
    out.push_back({stamp_ns, R * v});
  return out;
}

std::optional<Eigen::Isometry3d> BagDriveReader::groundTruthAt(int64_t stamp_ns,
                                                               double max_dt) const {
  const Eigen::Isometry3d* pose = nearest(impl_->ground_truth, stamp_ns, max_dt);
  if (!pose) return std::nullopt;
  return *pose;
}

std::optional<Eigen::Isometry3d> BagDriveReader::baseToFrame(const std::string& frame) const {
  // Breadth-first search over the static transforms (both directions) from base_link.
  std::map<std::string, Eigen::Isometry3d> reached{
      {impl_->topics.base_frame, Eigen::Isometry3d::Identity()}};
  std::deque<std::string> queue{impl_->topics.base_frame};
  while (!queue.empty()) {
    const std::string at = queue.front();
    queue.pop_front();
    if (at == frame) return reached.at(at);
    for (const StaticEdge& e : impl_->static_tf) {
      if (e.parent == at && !reached.count(e.child)) {
        reached[e.child] = reached.at(at) * e.parent_T_child;
        queue.push_back(e.child);
      } else if (e.child == at && !reached.count(e.parent)) {
        reached[e.parent] = reached.at(at) * e.parent_T_child.inverse();
        queue.push_back(e.parent);
      }
    }
  }
  return std::nullopt;
}

std::optional<BagCloud> BagDriveReader::nextCloud() {
  if (!impl_->clouds || impl_->cloud_it == impl_->clouds->end()) return std::nullopt;
  const rosbag::MessageInstance& m = *impl_->cloud_it;
  BagCloud out;
  out.stamp_ns = static_cast<int64_t>(m.getTime().toNSec());
  try {
    if (auto msg = m.instantiate<sensor_msgs::PointCloud2>()) {
      out.stamp_ns = static_cast<int64_t>(msg->header.stamp.toNSec());
      out.frame_id = msg->header.frame_id;
      auto cloud = std::make_shared<PointCloud>();
      if (fromPointCloud2(*msg, *cloud, &out.error)) out.cloud = cloud;
    } else {
      out.error = "message on '" + m.getTopic() + "' is a " + m.getDataType() +
                  ", not a sensor_msgs/PointCloud2";
    }
  } catch (const std::exception& e) {
    out.error = std::string("cannot read cloud message: ") + e.what();
  }
  ++impl_->cloud_it;
  return out;
}

}  // namespace osm_graph_slam
