#include "osm_graph_slam/ros/keyframe_conversions.h"

#include <memory>

#include "osm_graph_slam/common/upper_triangle.h"
#include "osm_graph_slam/ros/conversions.h"

namespace osm_graph_slam {

void toKeyFrameMsg(const KeyframeInput& kf, KeyFrame& msg) {
  msg.id = kf.id;
  msg.odom_pose = toPoseMsg(kf.odom_pose);
  msg.accum_distance = kf.accum_distance;
  msg.fitness = kf.odom_fitness;
  msg.tracking_recovered = kf.reanchored;
  msg.odom_hessian.clear();
  if (!kf.odom_hessian.isZero()) msg.odom_hessian = upperTriangle(kf.odom_hessian);
  msg.prediction_error.x = kf.odom_prediction_error.x();
  msg.prediction_error.y = kf.odom_prediction_error.y();
  msg.prediction_error.z = kf.odom_prediction_error.z();
}

bool fromKeyFrameMsg(const KeyFrame& msg, KeyframeInput& kf, std::string* cloud_error) {
  kf = KeyframeInput();
  kf.id = msg.id;
  kf.stamp = msg.header.stamp.toSec();
  kf.odom_pose = fromPoseMsg(msg.odom_pose);
  kf.accum_distance = msg.accum_distance;
  kf.odom_fitness = msg.fitness;
  kf.reanchored = msg.tracking_recovered;
  kf.odom_prediction_error = {msg.prediction_error.x, msg.prediction_error.y,
                              msg.prediction_error.z};
  if (msg.odom_hessian.size() == 21)
    kf.odom_hessian = upperTriangleToMatrix(msg.odom_hessian, 0, 6);
  auto cloud = std::make_shared<PointCloud>();
  if (!fromPointCloud2(msg.cloud, *cloud, cloud_error)) return false;
  kf.cloud = cloud;
  return true;
}

}  // namespace osm_graph_slam
