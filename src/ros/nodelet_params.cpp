#include "osm_graph_slam/ros/nodelet_params.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, PrefilteringNodeletParams& p) {
  r.param("base_link_frame", p.base_link_frame);
  r.param("sensor_to_base_from_tf", p.sensor_to_base_from_tf);
  r.param("tf_timeout", p.tf_timeout);
  r.param("warn_throttle_period", p.warn_throttle_period);
  r.param("reuse_freed_memory", p.reuse_freed_memory);
}

void readParams(const ParamReader& r, ScanMatchingNodeletParams& p) {
  r.param("odom_frame", p.odom_frame);
  r.param("base_link_frame", p.base_link_frame);
  r.param("sensor_frame", p.sensor_frame);
  r.param("publish_tf", p.publish_tf);
  r.param("warn_throttle_period", p.warn_throttle_period);
  r.param("imu_wait_timeout", p.imu_wait_timeout);
}

void readParams(const ParamReader& r, LineExtractionNodeletParams& p) {
  r.param("base_frame", p.base_frame);
  r.param("marker_z", p.marker_z);
}

void readParams(const ParamReader& r, LoopDetectionNodeletParams& p) {
  r.param("mode", p.mode);
  r.param("relocalize_after_restart", p.relocalize_after_restart);
  r.param("input_queue_size", p.input_queue_size);
}

void readParams(const ParamReader& r, OsmBufferNodeletParams& p) {
  r.param("source", p.source);
  r.param("osm_file", p.osm_file);
  r.param("map_frame", p.map_frame);
  r.param("update_period", p.update_period);
  r.param("min_publish_distance", p.min_publish_distance);
}

void readParams(const ParamReader& r, GraphBackendNodeletParams& p) {
  r.param("map_frame", p.map_frame);
  r.param("odom_frame", p.odom_frame);
  r.param("base_link_frame", p.base_link_frame);
  r.param("optimization_period", p.optimization_period);
  r.param("optimize_every_keyframes", p.optimize_every_keyframes);
  r.param("optimization_max_duty_cycle", p.optimization_max_duty_cycle);
  r.param("tf_publish_rate", p.tf_publish_rate);
  r.param("map_cloud_resolution", p.map_cloud_resolution);
  r.param("warn_throttle_period", p.warn_throttle_period);
  r.param("input_queue_size", p.input_queue_size);
  r.param("resume_map", p.resume_map);
  r.param("handover", p.handover);
  r.param("handover_leave_after", p.handover_leave_after);
  r.param("handover_ties", p.handover_ties);
  r.param("localization_ns", p.localization_ns);
  r.param("loop_detection_ns", p.loop_detection_ns);
}

void readParams(const ParamReader& r, LocalizationNodeletParams& p) {
  r.param("map_frame", p.map_frame);
  r.param("odom_frame", p.odom_frame);
  r.param("base_link_frame", p.base_link_frame);
  r.param("sensor_frame", p.sensor_frame);
  r.param("publish_tf", p.publish_tf);
  r.param("publish_odom_tf", p.publish_odom_tf);
  r.param("use_imu", p.use_imu);
  r.param("imu_max_gap", p.imu_max_gap);
  r.param("use_gnss", p.use_gnss);
  r.param("map_points_voxel", p.map_points_voxel);
  r.param("warn_throttle_period", p.warn_throttle_period);
  r.param("map_dir", p.map_dir);
  r.param("osm_file", p.osm_file);
  r.param("line_extraction_ns", p.line_extraction_ns);
  r.param("line_matcher_ns", p.line_matcher_ns);
  r.param("stop_when_mapping", p.stop_when_mapping);
}

void readParams(const ParamReader& r, OsmLocalizationNodeletParams& p) {
  r.param("map_frame", p.map_frame);
  r.param("odom_frame", p.odom_frame);
  r.param("base_link_frame", p.base_link_frame);
  r.param("publish_tf", p.publish_tf);
  r.param("use_imu", p.use_imu);
  r.param("warn_throttle_period", p.warn_throttle_period);
  r.param("line_extraction_ns", p.line_extraction_ns);
  r.param("line_matcher_ns", p.line_matcher_ns);
}

bool readParams(const ParamReader& r, RadarOdometryNodeletParams& p, std::string* error) {
  r.param("radar_odom_frame", p.radar_odom_frame);
  r.param("radar_map_frame", p.radar_map_frame);
  r.param("radar_frame", p.radar_frame);
  r.param("publish_tf", p.publish_tf);
  r.param("warn_throttle_period", p.warn_throttle_period);
  r.param("nav_queue_size", p.nav_queue_size);
  if (p.radar_odom_frame.empty() || p.radar_map_frame.empty() || p.radar_frame.empty() ||
      p.radar_map_frame == p.radar_odom_frame || !(p.warn_throttle_period > 0.0) ||
      p.nav_queue_size < 1) {
    if (error)
      *error =
          "radar_odom_frame, radar_map_frame and radar_frame must not be empty, radar_map_frame "
          "!= radar_odom_frame, warn_throttle_period > 0, nav_queue_size >= 1";
    return false;
  }
  return true;
}

}  // namespace osm_graph_slam
