// line_extraction: keyframe cloud (base_link) -> wall line segments (base_link) + rviz markers.
// Thin adapter: parameters -> core structs, messages <-> core types; the algorithms live in
// cloud/WallPointExtractor and lines/LineSegmentExtractor.
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <pluginlib/class_list_macros.hpp>

#include "osm_graph_slam/ros/nodelet_logging.h"

#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/LineSegmentArray.h"
#include "osm_graph_slam/cloud/params_io.h"
#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/common/sequence_gaps.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/lines/params_io.h"
#include "osm_graph_slam/ros/conversions.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {

class LineExtractionNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    logger_ = std::make_shared<Logger>(nodeletLogSink(getName()));
    const RosParamReader reader(pnh);
    WallPointExtractorParams wp;
    readParams(PrefixedParamReader(reader, "wall"), wp);
    LineSegmentExtractorParams lp;
    readParams(PrefixedParamReader(reader, "segments"), lp);
    LineExtractionNodeletParams np;  // defaults: nodelet_params.h
    readParams(reader, np);
    base_frame_ = np.base_frame;
    marker_z_ = np.marker_z;

    walls_ = std::make_unique<WallPointExtractor>(wp, logger_);
    segments_ = std::make_unique<LineSegmentExtractor>(lp);
    segments_pub_ = nh.advertise<LineSegmentArray>("line_segments", 10);
    markers_pub_ = nh.advertise<visualization_msgs::MarkerArray>("line_markers", 2);
    keyframe_sub_ = nh.subscribe("keyframe", 100, &LineExtractionNodelet::onKeyFrame, this);
    NODELET_INFO(
        "line_extraction: horizon %.2f m, voxel %.2f m, k %d, normal angle %.1f deg; "
        "RANSAC threshold %.2f m, min cluster %d, min length %.1f m",
        wp.horizon_height, wp.voxel_size, wp.k_neighbors, wp.max_normal_angle_deg,
        lp.distance_threshold, lp.min_cluster_size, lp.min_segment_length);
  }

 private:
  void onKeyFrame(const KeyFrame::ConstPtr& kf) {
    if (keyframe_ids_.observe(kf->id) > 0)
      NODELET_WARN_THROTTLE(10.0,
                            "keyframes (%s) never reached line_extraction (%lu so far): "
                            "its queue overflowed; the back-end gets no segments for them",
                            keyframe_ids_.lastGap().c_str(), keyframe_ids_.missing());
    PointCloud cloud;
    std::string error;
    if (!fromPointCloud2(kf->cloud, cloud, &error)) {
      logger_->warnOnce("bad_cloud",
                        "line_extraction: cannot convert the keyframe cloud "
                        "(publishing no segments): " +
                            error);
      cloud.clear();
    }
    WallPointStats wstats;
    const PointCloudPtr walls = walls_->extract(cloud, &wstats);
    LineSegmentStats lstats;
    const std::vector<LineSegment2> segments = segments_->extract(*walls, &lstats);

    auto out = boost::make_shared<LineSegmentArray>();
    out->header.stamp = kf->header.stamp;
    out->header.frame_id =
        kf->cloud.header.frame_id.empty() ? base_frame_ : kf->cloud.header.frame_id;
    out->keyframe_id = kf->id;
    out->segments.reserve(segments.size());
    for (const auto& s : segments) {
      osm_graph_slam::LineSegment m;
      m.start.x = s.start.x();
      m.start.y = s.start.y();
      m.end.x = s.end.x();
      m.end.y = s.end.y();
      m.support = s.support;
      out->segments.push_back(m);
    }
    NODELET_DEBUG("keyframe %lu: %zu points -> %zu wall points -> %zu segments (%.1f + %.1f ms)",
                  static_cast<unsigned long>(kf->id), wstats.input, wstats.walls, segments.size(),
                  wstats.ms, lstats.ms);
    if (markers_pub_.getNumSubscribers() > 0) markers_pub_.publish(markersOf(*out));
    segments_pub_.publish(boost::static_pointer_cast<const LineSegmentArray>(out));
  }

  visualization_msgs::MarkerArray markersOf(const LineSegmentArray& segs) const {
    visualization_msgs::MarkerArray arr;
    visualization_msgs::Marker clear;
    clear.action = visualization_msgs::Marker::DELETEALL;
    arr.markers.push_back(clear);
    visualization_msgs::Marker m;
    m.header = segs.header;
    m.ns = "line_segments";
    m.id = 0;
    m.type = visualization_msgs::Marker::LINE_LIST;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.scale.x = 0.15;
    m.color.r = 1.0f;
    m.color.g = 0.5f;
    m.color.a = 1.0f;
    for (const auto& s : segs.segments) {
      geometry_msgs::Point a = s.start, b = s.end;
      a.z = b.z = marker_z_;
      m.points.push_back(a);
      m.points.push_back(b);
    }
    if (!m.points.empty()) arr.markers.push_back(m);
    return arr;
  }

  std::shared_ptr<const Logger> logger_;
  std::unique_ptr<WallPointExtractor> walls_;
  std::unique_ptr<LineSegmentExtractor> segments_;
  ros::Subscriber keyframe_sub_;
  SequenceGaps keyframe_ids_;  ///< counts keyframes lost in the subscription queue
  ros::Publisher segments_pub_, markers_pub_;
  std::string base_frame_;
  double marker_z_{};  // onInit()
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::LineExtractionNodelet, nodelet::Nodelet)
