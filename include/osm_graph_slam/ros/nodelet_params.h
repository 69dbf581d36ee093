#pragma once
// Parameters of the ROS adapters themselves (frames, TF, rates, sources), one struct per nodelet.
// They are read by readParams() like every core stage's, so their defaults are written once (the
// initialisers below) and config_consistency_test audits config/<nodelet>.yaml against them.
// Plain data, no ROS. Lists (sensor_to_base, origin, initial_pose) stay with the nodelets: the
// ParamReader interface has no list type.
#include <string>

#include "osm_graph_slam/common/param_reader.h"

namespace osm_graph_slam {

struct PrefilteringNodeletParams {
  std::string base_link_frame = "base_link";
  bool sensor_to_base_from_tf = true;  ///< else the sensor_to_base list
  double tf_timeout = 0.2;             ///< [s]
  double warn_throttle_period = 5.0;   ///< [s]
  /// Keep freed scan buffers in the heap (process-wide; common/memory_tuning.h).
  bool reuse_freed_memory = true;
};

struct ScanMatchingNodeletParams {
  std::string odom_frame = "odom";
  std::string base_link_frame = "base_link";
  /// The LiDAR's frame: deskewing takes each point's azimuth about it (TF base_link <- it).
  std::string sensor_frame = "velo_link";
  bool publish_tf = true;
  double warn_throttle_period = 5.0;  ///< [s]
  /// [s] of wall time a scan waits for the IMU sample at or after its stamp (0: never waits).
  double imu_wait_timeout = 0.3;
};

struct LineExtractionNodeletParams {
  std::string base_frame = "base_link";
  double marker_z = 0.0;  ///< [m] height of the segment markers
};

struct LoopDetectionNodeletParams {
  std::string mode = "odometry";  ///< odometry | place_recognition
  /// Odometry mode: after a tracking restart (the time jumped back) this many keyframes search
  /// every stored keyframe, as place_recognition does, until one finds a loop (0: never).
  int relocalize_after_restart = 10;
  int input_queue_size = 1000;  ///< keyframe subscription (its own thread; see the nodelet)
};

struct OsmBufferNodeletParams {
  std::string source = "overpass";  ///< overpass | file
  std::string osm_file;
  std::string map_frame = "map";
  double update_period = 0.5;         ///< [s]
  double min_publish_distance = 1.0;  ///< [m]
};

struct GraphBackendNodeletParams {
  std::string map_frame = "map";
  std::string odom_frame = "odom";
  std::string base_link_frame = "base_link";
  double optimization_period = 3.0;  ///< [s]
  /// > 0: optimise after every this many keyframes instead of every optimization_period
  /// (optimization_schedule.h: keyframeUpdateDue); replays then give the same graph under load.
  int optimize_every_keyframes = 0;
  double optimization_max_duty_cycle = 0.5;  ///< share of a core (optimization_schedule.h)
  double tf_publish_rate = 20.0;             ///< [Hz]
  double map_cloud_resolution = 0.5;         ///< [m]
  double warn_throttle_period = 5.0;         ///< [s]
  int input_queue_size = 1000;  ///< messages per input topic (keyframes: ~5 min of driving)
  /// A folder save_map wrote: mapping continues on it as a new session (slam/map_resume.h).
  std::string resume_map;
  /// With resume_map: the localization nodelet tracks on the map (localization/status) and
  /// mapping starts only once it has left it (slam/localization_handover.h).
  bool handover = false;
  double handover_leave_after = 2.0;  ///< [s] LocalizationHandoverParams::leave_after
  int handover_ties = 3;              ///< LocalizationHandoverParams::ties
  /// Where the launch file loaded the localiser's and the loop detector's parameters: the
  /// resumed map's placement and inter-session loops use them (absent keys: their defaults).
  std::string localization_ns = "/localization";
  std::string loop_detection_ns = "/loop_detection";
};

struct LocalizationNodeletParams {
  std::string map_frame = "map";
  std::string odom_frame = "odom";
  std::string base_link_frame = "base_link";
  /// The LiDAR's frame: deskewing takes each point's azimuth about it (TF base_link <- it).
  std::string sensor_frame = "velo_link";
  bool publish_tf = true;
  bool publish_odom_tf = true;
  bool use_imu = true;
  double imu_max_gap = 0.2;           ///< [s]
  bool use_gnss = true;               ///< gps/fix checks the pose (gnss_check_distance)
  double map_points_voxel = 0.5;      ///< [m]
  double warn_throttle_period = 5.0;  ///< [s]
  std::string map_dir;
  std::string osm_file;
  /// Where the SLAM pipeline's wall/segment and line-matcher parameters were loaded (global
  /// search by the OSM walls; launch/localization.launch loads them as osm_localization.launch).
  std::string line_extraction_ns = "/line_extraction";
  std::string line_matcher_ns = "/graph_backend/line_matcher";
  /// A hand-over (graph_backend ~handover): once slam/mapping says the SLAM back-end maps, this
  /// nodelet stops (no pose, no TF: graph_backend publishes map -> odom from then on).
  bool stop_when_mapping = false;
};

struct OsmLocalizationNodeletParams {
  std::string map_frame = "map";  ///< ENU at the origin (osm_buffer's first fix)
  std::string odom_frame = "odom";
  std::string base_link_frame = "base_link";
  bool publish_tf = true;  ///< TF map -> odom from the localised pose and the tracker's
  bool use_imu = true;     ///< the IMU heading at the start (else the walls' global match)
  double warn_throttle_period = 5.0;  ///< [s]
  /// Where the SLAM pipeline's wall/segment and line-matcher parameters were loaded
  /// (launch/osm_localization.launch loads config/line_extraction.yaml and graph_backend.yaml).
  std::string line_extraction_ns = "/line_extraction";
  std::string line_matcher_ns = "/graph_backend/line_matcher";
};

struct RadarOdometryNodeletParams {
  std::string radar_odom_frame = "radar_odom";  ///< parent of radar/odom and of the TF
  /// Loop-corrected map frame (loop/enabled): TF radar_map_frame -> radar_odom_frame.
  std::string radar_map_frame = "radar_map";
  /// Child frame when an image comes without a frame_id (mulran2bag's frame).
  std::string radar_frame = "radar_polar";
  bool publish_tf = true;             ///< TF radar_odom_frame -> the image's frame
  double warn_throttle_period = 5.0;  ///< [s]
  /// Subscriber queue of gps/fix and of imu/data (loop/enabled): a 100 Hz IMU fills 1000 in
  /// 10 s, more than a sweep with a loop search and an optimisation takes.
  int nav_queue_size = 1000;
};

void readParams(const ParamReader& r, PrefilteringNodeletParams& p);
void readParams(const ParamReader& r, ScanMatchingNodeletParams& p);
void readParams(const ParamReader& r, LineExtractionNodeletParams& p);
void readParams(const ParamReader& r, LoopDetectionNodeletParams& p);
void readParams(const ParamReader& r, OsmBufferNodeletParams& p);
void readParams(const ParamReader& r, GraphBackendNodeletParams& p);
void readParams(const ParamReader& r, LocalizationNodeletParams& p);
void readParams(const ParamReader& r, OsmLocalizationNodeletParams& p);
/// False with the reason for an empty frame name, a non-positive throttle period or queue size.
bool readParams(const ParamReader& r, RadarOdometryNodeletParams& p, std::string* error);

}  // namespace osm_graph_slam
