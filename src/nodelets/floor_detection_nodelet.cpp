// floor_detection: keyframe cloud (base_link) -> floor plane coefficients (ART-SLAM §3.1.6).
// Thin adapter: the algorithm is cloud/FloorDetector; the back-end ties consecutive floors.
#include <nodelet/nodelet.h>
#include <ros/ros.h>

#include <pluginlib/class_list_macros.hpp>

#include "osm_graph_slam/FloorCoeffs.h"
#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/cloud/floor_detector.h"
#include "osm_graph_slam/cloud/params_io.h"
#include "osm_graph_slam/common/sequence_gaps.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {

class FloorDetectionNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    FloorDetectorParams params;
    readParams(RosParamReader(getPrivateNodeHandle()), params);
    detector_ = std::make_unique<FloorDetector>(params);
    health_ = std::make_unique<FloorHealth>(params.warn_after_missing);
    floor_pub_ = nh.advertise<FloorCoeffs>("floor_coeffs", 100);
    if (!params.enabled) {  // no floors, and no "no floor" warnings either
      NODELET_INFO("floor_detection off (enabled: false): no floor_coeffs");
      return;
    }
    keyframe_sub_ = nh.subscribe("keyframe", 100, &FloorDetectionNodelet::onKeyFrame, this);
    NODELET_INFO(
        "floor_detection on: floor at z %.2f +- %.2f m in %.0f-%.0f m, RANSAC %.2f m, "
        "min %d inliers, rough-terrain radius %.1f m",
        params.floor_z, params.floor_z_tolerance, params.min_range, params.max_range,
        params.ransac_distance, params.min_inliers, params.rough_radius);
  }

 private:
  void onKeyFrame(const KeyFrame::ConstPtr& kf) {
    if (keyframe_ids_.observe(kf->id) > 0)
      NODELET_WARN_THROTTLE(10.0,
                            "keyframes (%s) never reached floor_detection (%lu so far): "
                            "its queue overflowed; the back-end gets no floor for them",
                            keyframe_ids_.lastGap().c_str(), keyframe_ids_.missing());
    PointCloud cloud;
    std::string error;
    FloorDetection floor;
    if (fromPointCloud2(kf->cloud, cloud, &error)) {
      floor = detector_->detect(cloud);
    } else {
      floor.reason = "keyframe cloud not usable: " + error;
    }
    const std::string message = health_->update(kf->id, floor);
    if (!message.empty()) NODELET_WARN("%s", message.c_str());
    auto out = boost::make_shared<FloorCoeffs>();
    out->header.stamp = kf->header.stamp;
    out->header.frame_id = kf->cloud.header.frame_id;
    out->keyframe_id = kf->id;
    out->found = floor.found;
    for (int i = 0; i < 4; ++i) out->coeffs[i] = floor.coeffs[i];
    out->method = floor.method;
    out->inliers = static_cast<uint32_t>(floor.inliers);
    out->rms = floor.rms;
    out->reason = floor.reason;
    floor_pub_.publish(boost::static_pointer_cast<const FloorCoeffs>(out));
  }

  std::unique_ptr<FloorDetector> detector_;
  std::unique_ptr<FloorHealth> health_;
  ros::Subscriber keyframe_sub_;
  SequenceGaps keyframe_ids_;  ///< counts keyframes lost in the subscription queue
  ros::Publisher floor_pub_;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::FloorDetectionNodelet, nodelet::Nodelet)
