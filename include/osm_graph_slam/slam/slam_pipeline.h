#pragma once
// The whole SLAM pipeline in one object, without ROS: prefilter -> keyframe tracker -> wall
// segments -> loop detection -> OSM buffer -> graph back-end. The offline runner drives it as
// fast as the CPU allows; the nodelets run the same stages, connected by topics.
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/cloud/floor_detector.h"
#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/odometry/tracking_health.h"
#include "osm_graph_slam/osm/osm_buffer.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/keyframe_input.h"
#include "osm_graph_slam/slam/localization_handover.h"
#include "osm_graph_slam/slam/map_resume.h"

namespace osm_graph_slam {

struct SlamPipelineParams {
  CloudPrefilterParams prefilter;
  KeyframeTrackerParams tracker;
  FloorDetectorParams floor;
  WallPointExtractorParams wall;
  LineSegmentExtractorParams segments;
  bool use_loops = true;
  LoopDetectorParams loop;
  OsmBufferParams osm;
  GraphBackendParams backend;
  /// The nodelet optimises on a timer (3 s = 30 scans at 10 Hz); offline, every N keyframes.
  int optimize_every_keyframes = 15;
};

/// Milliseconds spent per stage over the whole run.
struct PipelineTimings {
  size_t scans = 0, keyframes = 0, loops = 0;
  size_t global_priors = 0, global_rejected = 0, building_edges = 0, overlap_edges = 0;
  size_t shared_walls = 0;  ///< building pairs tied by a shared wall (latest update)
  size_t gnss_gated = 0;    ///< fixes kept out by the innovation gate
  double input_ms = 0;      ///< reading the scans (measured by the caller: addInputTime)
  double prefilter_ms = 0, tracking_ms = 0, walls_ms = 0, segments_ms = 0, loops_ms = 0, osm_ms = 0,
         backend_ms = 0;
  double pre_tracker_ms = 0;     ///< inside tracking_ms: the pre-tracker's registrations
  double floor_ms = 0;           ///< floor detection (keyframes only)
  double localization_ms = 0;    ///< on the saved map before a hand-over (handOverOn)
  bool prefilter_ahead = false;  ///< prefiltered on another thread (processFiltered): overlapped
  size_t floors_found = 0, floors_missing = 0, floor_edges = 0, floor_slope_changes = 0;
  /// Back-end updates: all, windowed (optimization_window), full batches a loop called for, and
  /// the slowest one.
  size_t updates = 0, windowed_updates = 0, loop_full_batches = 0;
  double slowest_update_ms = 0;
  BackendUpdateReport::StageMs backend_stage_ms;  ///< inside backend_ms, summed over the updates
  double wall_time_s = 0;                         ///< from the first scan to finish()
  TrackingStats tracking;  ///< failed matches, lost tracks, the longest span without keyframe
  /// The first heading, when global matching against OSM found it (no IMU heading given).
  std::optional<BackendUpdateReport::HeadingFromMap> heading_from_map;
  double scansPerSecond() const { return wall_time_s > 0 ? scans / wall_time_s : 0.0; }
};

class SlamPipeline {
 public:
  /// osm_source may be null (no OSM priors: odometry + loops only).
  SlamPipeline(const SlamPipelineParams& params, std::shared_ptr<OsmMapSource> osm_source,
               std::shared_ptr<const Logger> logger = nullptr);
  ~SlamPipeline();

  /// The first valid GPS fix: the map origin. Needed before OSM buildings can be used.
  void setOrigin(double lat, double lon, double alt);
  /// Continues the map save_map wrote in `directory` (slam/map_resume.h): its graph is replayed
  /// and this drive becomes a new session of it, in its frame (its origin replaces setOrigin's;
  /// the drive's start heading, when known, is the session's). Call before the first scan.
  /// False with the reason; the pipeline then maps on its own as before.
  bool resumeOn(const std::string& directory, const MapResumeParams& resume,
                const LocalizationParams& localization, std::string* error);
  /// resumeOn, but this drive first localises on the saved map (its localiser, every scan) and
  /// maps only once it has left it (slam/localization_handover.h): the session starts at the
  /// last keyframes the localiser tracked, placed by its poses of them.
  bool handOverOn(const std::string& directory, const MapResumeParams& resume,
                  const LocalizationParams& localization,
                  const LocalizationHandoverParams& handover, std::string* error);
  /// Where the resumed session stands (null without resumeOn).
  const MapResume* resume() const { return resume_.get(); }
  /// The hand-over's state (null without handOverOn).
  const LocalizationHandover* handover() const { return handover_.get(); }
  /// The localiser's poses (map frame) of the scans before the hand-over.
  const Trajectory& localizedPoses() const { return localized_; }
  /// The drive's poses in the map frame, whole: the localiser's before the first mapped
  /// keyframe, then the live session's keyframes (without a hand-over: those alone).
  Trajectory drivePoses() const;
  /// One raw scan in the sensor frame (sensor -> base_link from params.prefilter) with what the
  /// other sensors say at its time. Bad scans are reported and skipped; returns true if the scan
  /// produced a pose.
  bool processScan(double stamp, const PointCloudConstPtr& sensor_cloud,
                   const ScanAiding& aiding = {});
  /// processScan for a scan prefiltered elsewhere with prefilter() (offline_slam runs it on its
  /// reading thread, one scan ahead of the tracking); prefilter_ms is reported in its stage.
  /// sensor_cloud: the raw scan, which the multi_cue tracker projects (usesSensorCloud()).
  bool processFiltered(double stamp, const CloudPrefilterResult& filtered, double prefilter_ms,
                       const ScanAiding& aiding = {},
                       const PointCloudConstPtr& sensor_cloud = nullptr);
  /// Whether the tracker reads the raw scan (tracker: multi_cue): a caller that prefilters
  /// ahead must then keep it for processFiltered.
  bool usesSensorCloud() const { return params_.tracker.tracker == "multi_cue"; }
  /// Starts the wall clock of the throughput report (else the first scan starts it): a caller
  /// that reads or prefilters ahead starts it before, so that work is counted too.
  void startClock();
  /// The pipeline's prefilter; filter() is const and may run on another thread.
  const CloudPrefilter& prefilter() const { return prefilter_; }
  /// Flushes every queue and runs the final optimisation.
  BackendUpdateReport finish();
  /// Time the caller waited for input (files, a bag), so the report shows it next to the
  /// stages: on a cold disk reading can take as long as all of them.
  void addInputTime(double ms) { timings_.input_ms += ms; }

  const GraphBackend& backend() const { return *backend_; }
  PipelineTimings timings() const;
  std::string timingTable() const;
  std::string timingJson() const;

 private:
  GraphBackendParams backendParams() const;
  void startOsmBuffer(const EnuConverter& origin);
  /// "odometry scale: ..." (empty when the scale is not estimated).
  std::string scaleLine() const;
  bool trackFiltered(double stamp, const CloudPrefilterResult& filtered, double prefilter_ms,
                     const ScanAiding& aiding, const PointCloudConstPtr& sensor_cloud);
  /// backend_->update(), accounted; with search_frame map the loop database follows it.
  void updateBackend();
  void account(const BackendUpdateReport& report);
  void logTracking(const std::optional<TrackingEvent>& event) const;
  void processKeyframe(const Keyframe& kf, const TrackResult& track, const ScanAiding& aiding);
  /// One keyframe into the graph: loops, walls, buildings, the back-end's update. `localized`:
  /// the hand-over's localiser pose of it.
  void mapKeyframe(KeyframeInput input, const std::optional<Eigen::Isometry3d>& localized);
  /// The scan on the saved map until the hand-over.
  void localize(double stamp, const PointCloudConstPtr& cloud,
                const std::optional<Eigen::Quaterniond>& imu_orientation);

  SlamPipelineParams params_;
  std::shared_ptr<const Logger> logger_;
  std::shared_ptr<OsmMapSource> osm_source_;
  CloudPrefilter prefilter_;
  KeyframeTracker tracker_;
  TrackingHealth tracking_;
  FloorDetector floor_;
  FloorHealth floor_health_;
  WallPointExtractor walls_;
  LineSegmentExtractor segments_;
  bool loop_search_in_map_;  ///< params.loop.search_frame == "map"
  std::unique_ptr<LoopDetector> loops_;
  std::unique_ptr<OsmBuffer> osm_buffer_;
  std::unique_ptr<GraphBackend> backend_;
  std::unique_ptr<MapResume> resume_;
  std::unique_ptr<LocalizationHandover> handover_;
  Trajectory localized_;
  std::optional<std::pair<double, Eigen::Quaterniond>> last_imu_orientation_;  ///< stamp, q
  size_t mapped_keyframes_ = 0;
  KeyframeAiding aiding_;
  PipelineTimings timings_;
  size_t keyframes_since_update_ = 0;
  std::chrono::steady_clock::time_point start_;
  bool started_ = false;
};

}  // namespace osm_graph_slam
