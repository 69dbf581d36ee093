#include "osm_graph_slam/slam/slam_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// Adds the elapsed milliseconds of a scope to a counter.
class StageTimer {
 public:
  explicit StageTimer(double& total) : total_(total), t0_(Clock::now()) {}
  ~StageTimer() { total_ += std::chrono::duration<double, std::milli>(Clock::now() - t0_).count(); }

 private:
  double& total_;
  Clock::time_point t0_;
};

/// The tracker deskews in base_link and needs the LiDAR's mounting to know each point's azimuth.
KeyframeTrackerParams trackerParams(const SlamPipelineParams& params) {
  KeyframeTrackerParams tracker = params.tracker;
  tracker.sensor_to_base = params.prefilter.sensor_to_base;
  return tracker;
}

}  // namespace

SlamPipeline::SlamPipeline(const SlamPipelineParams& params,
                           std::shared_ptr<OsmMapSource> osm_source,
                           std::shared_ptr<const Logger> logger)
    : params_(params),
      logger_(logger ? std::move(logger) : std::make_shared<Logger>()),
      osm_source_(std::move(osm_source)),
      prefilter_(params.prefilter),
      tracker_(trackerParams(params)),
      tracking_(params.tracker.lost_track_after),
      floor_(params.floor),
      floor_health_(params.floor.warn_after_missing),
      walls_(params.wall, logger_),
      segments_(params.segments),
      loop_search_in_map_(params.loop.search_frame == "map"),
      // Offline, the runner states the drive's start heading as the known one (initial_yaw);
      // without it the first global matching sets the heading, never the IMU.
      aiding_(params.backend.inputs,
              params.backend.initial_yaw_known ? std::optional<double>(params.backend.initial_yaw)
                                               : std::nullopt,
              /*heading_from_imu=*/false, /*keep_fixes=*/true) {
  backend_ = std::make_unique<GraphBackend>(backendParams(), logger_);
  if (params.loop.search_frame != "odometry" && params.loop.search_frame != "map")
    logger_->warn("loop search_frame '" + params.loop.search_frame +
                  "' unknown (odometry | map): searching around odometry poses");
  if (params.use_loops) {
    const std::shared_ptr<const Logger> log = logger_;
    loops_ = std::make_unique<LoopDetector>(
        params.loop, [log](LogLevel level, const std::string& msg) { log->log(level, msg); });
  }
}

SlamPipeline::~SlamPipeline() = default;

GraphBackendParams SlamPipeline::backendParams() const {
  GraphBackendParams backend = params_.backend;
  backend.use_osm = backend.use_osm && osm_source_ != nullptr;
  return backend;
}

void SlamPipeline::setOrigin(double lat, double lon, double alt) {
  if (backend_->hasOrigin()) return;
  backend_->setOrigin(lat, lon, alt);
  startOsmBuffer(EnuConverter(lat, lon, alt));
}

void SlamPipeline::startOsmBuffer(const EnuConverter& origin) {
  if (osm_source_ && backend_->params().use_osm)
    osm_buffer_ = std::make_unique<OsmBuffer>(osm_source_, origin, params_.osm, logger_);
}

bool SlamPipeline::resumeOn(const std::string& directory, const MapResumeParams& resume,
                            const LocalizationParams& localization, std::string* error) {
  // The saved map's first session keeps the heading it started with; this drive's known one
  // (initial_yaw) is its own session's start.
  GraphBackendParams params = backendParams();
  params.initial_yaw_known = false;
  auto backend = std::make_unique<GraphBackend>(params, logger_);
  resume_ =
      MapResume::load(directory, resume, localization, params_.loop, *backend, logger_, error);
  if (!resume_) return false;
  backend_ = std::move(backend);
  if (params_.backend.initial_yaw_known)
    backend_->setSessionHeading(resume_->session(), params_.backend.initial_yaw);
  if (const auto origin = backend_->origin()) startOsmBuffer(*origin);
  return true;
}

bool SlamPipeline::handOverOn(const std::string& directory, const MapResumeParams& resume,
                              const LocalizationParams& localization,
                              const LocalizationHandoverParams& handover, std::string* error) {
  if (!resumeOn(directory, resume, localization, error)) return false;
  handover_ = std::make_unique<LocalizationHandover>(handover);
  logger_->info("localising on the saved map; mapping starts when the drive has left it (" +
                std::to_string(handover.leave_after) + " s not tracked)");
  return true;
}

void SlamPipeline::localize(double stamp, const PointCloudConstPtr& cloud,
                            const std::optional<Eigen::Quaterniond>& imu_orientation) {
  StageTimer t(timings_.localization_ms);
  // The filter's motion model turns with the gyro; without one it assumes a constant turn rate
  // and loses the map in sharp turns. The rate is the IMU orientation's change since the last
  // scan, in base_link.
  std::optional<Eigen::Vector3d> gyro;
  if (imu_orientation && last_imu_orientation_ && stamp > last_imu_orientation_->first) {
    const Eigen::AngleAxisd turn(last_imu_orientation_->second.conjugate() * *imu_orientation);
    gyro = turn.axis() * turn.angle() / (stamp - last_imu_orientation_->first);
  }
  if (imu_orientation)
    last_imu_orientation_ = std::make_pair(stamp, *imu_orientation);
  else
    last_imu_orientation_.reset();
  const LocalizationOutput out = resume_->localizer().process(stamp, cloud, gyro);
  const bool tracking =
      out.status == LocalizationStatus::kTracking || out.status == LocalizationStatus::kRelocalized;
  if (out.status != LocalizationStatus::kUninitialized) localized_.push_back({stamp, out.pose});
  handover_->addLocalization(stamp, tracking, out.pose);
}

Trajectory SlamPipeline::drivePoses() const {
  Trajectory poses;
  const uint32_t session = resume_ ? resume_->session() : 0;
  for (const auto& kf : backend_->keyframes())
    if (kf.session == session) poses.push_back({kf.stamp, kf.map_pose});
  const double first_mapped = poses.empty() ? INFINITY : poses.front().stamp;
  Trajectory out;
  for (const auto& p : localized_)
    if (p.stamp < first_mapped) out.push_back(p);
  out.insert(out.end(), poses.begin(), poses.end());
  return out;
}

bool SlamPipeline::processScan(double stamp, const PointCloudConstPtr& sensor_cloud,
                               const ScanAiding& aiding) {
  startClock();
  if (!sensor_cloud) {
    ++timings_.scans;
    logger_->warnOnce("null_scan", "scan at " + std::to_string(stamp) + " has no cloud; skipped");
    logTracking(tracking_.updateRejected(stamp, "no cloud"));
    return false;
  }
  const auto t0 = Clock::now();
  const CloudPrefilterResult filtered = prefilter_.filter(*sensor_cloud);
  const double prefilter_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  return trackFiltered(stamp, filtered, prefilter_ms, aiding, sensor_cloud);
}

bool SlamPipeline::processFiltered(double stamp, const CloudPrefilterResult& filtered,
                                   double prefilter_ms, const ScanAiding& aiding,
                                   const PointCloudConstPtr& sensor_cloud) {
  timings_.prefilter_ahead = true;
  return trackFiltered(stamp, filtered, prefilter_ms, aiding, sensor_cloud);
}

bool SlamPipeline::trackFiltered(double stamp, const CloudPrefilterResult& filtered,
                                 double prefilter_ms, const ScanAiding& aiding,
                                 const PointCloudConstPtr& sensor_cloud) {
  startClock();
  ++timings_.scans;
  timings_.prefilter_ms += prefilter_ms;
  if (!filtered.ok) {
    logger_->warnOnce("bad_scan", "scan at " + std::to_string(stamp) +
                                      " skipped: " + filtered.reason + " (logged once)");
    logTracking(tracking_.updateRejected(stamp, filtered.reason));
    return false;
  }
  if (handover_ && !handover_->mapping()) localize(stamp, filtered.cloud, aiding.imu_orientation);
  TrackResult result;
  {
    StageTimer t(timings_.tracking_ms);
    result = tracker_.track(stamp, filtered.cloud, aiding.imu_orientation, sensor_cloud);
  }
  if (!result.notice.empty()) logger_->warn(result.notice);  // the tracker gives each once
  timings_.pre_tracker_ms += result.pre_tracker_ms;          // part of tracking, shown on its own
  logTracking(tracking_.update(stamp, result));
  if (!result.has_pose()) return false;
  if (result.new_keyframe) processKeyframe(tracker_.keyframe(), result, aiding);
  return true;
}

void SlamPipeline::startClock() {
  if (started_) return;
  start_ = Clock::now();
  started_ = true;
}

void SlamPipeline::processKeyframe(const Keyframe& kf, const TrackResult& track,
                                   const ScanAiding& aiding) {
  ++timings_.keyframes;
  KeyframeInput input = keyframeInput(kf, track);
  const std::optional<FirstHeading> first = aiding_.aid(aiding, input);
  if (first && first->from_imu && first->yaw) backend_->setInitialHeading(*first->yaw);
  if (first && !first->warning.empty()) logger_->warn(first->warning);
  if (params_.floor.enabled) {
    StageTimer t(timings_.floor_ms);
    const FloorDetection floor = floor_.detect(*kf.cloud);
    if (floor.found) input.floor = floor.coeffs;
    const std::string message = floor_health_.update(kf.id, floor);
    if (!message.empty()) logger_->warn(message);
  }
  if (!handover_) return mapKeyframe(std::move(input), std::nullopt);
  handover_->addKeyframe(input);
  for (auto& released : handover_->release())
    mapKeyframe(std::move(released.keyframe), released.localized);
}

void SlamPipeline::mapKeyframe(KeyframeInput input,
                               const std::optional<Eigen::Isometry3d>& localized) {
  ++mapped_keyframes_;
  if (resume_) resume_->renumber(input);  // the live session's ids from here on
  const uint64_t graph_id = input.id;
  backend_->addKeyframe(input);
  if (resume_)
    for (const auto& loop : resume_->process(input, *backend_, localized))
      backend_->addLoopClosure(loop);

  std::vector<LineSegment2> segments;
  if (backend_->params().use_osm) {
    PointCloudPtr wall_points;
    {
      StageTimer t(timings_.walls_ms);
      wall_points = walls_.extract(*input.cloud);
    }
    StageTimer t(timings_.segments_ms);
    segments = segments_.extract(*wall_points);
  }
  backend_->addLineSegments(graph_id, std::move(segments));

  if (loops_) {
    StageTimer t(timings_.loops_ms);
    LoopKeyframe lk;
    lk.id = graph_id;
    // In the map frame the search follows the back-end's corrections of the odometry's drift.
    lk.odom_pose = loop_search_in_map_ ? backend_->mapToOdom() * input.odom_pose : input.odom_pose;
    lk.accum_distance = input.accum_distance;
    lk.cloud = input.cloud;
    if (auto loop = loops_->process(lk)) {
      LoopClosureInput in;
      in.from_id = loop->from_id;
      in.to_id = loop->to_id;
      in.relative_pose = loop->relative_pose;
      in.information = loop->information;
      backend_->addLoopClosure(in);
      ++timings_.loops;
    }
  }

  if (osm_buffer_ && (resume_ ? mapped_keyframes_ == 1 : backend_->numKeyframes() == 0)) {
    // map->odom holds the origin and the heading only once the first keyframe is in the graph:
    // until the first update the queries below would be made in the odometry frame.
    StageTimer t(timings_.backend_ms);
    updateBackend();
  }
  if (osm_buffer_) {
    StageTimer t(timings_.osm_ms);
    // The query position is the keyframe's estimate in the map (map->odom of the last update).
    const Eigen::Vector2d position =
        (backend_->mapToOdom() * input.odom_pose).translation().head<2>();
    OsmQueryResult q = osm_buffer_->query(position);
    if (!q.buffer_valid && mapped_keyframes_ == 1) {
      // The very first fill is the only time the pipeline waits for the map (thesis §3.1).
      osm_buffer_->fillBlocking(position);
      q = osm_buffer_->query(position);
    }
    if (q.buffer_valid)
      backend_->addBuildings(std::move(q.buildings), position, osm_buffer_->params().query_radius);
  }

  if (++keyframes_since_update_ >= static_cast<size_t>(params_.optimize_every_keyframes)) {
    StageTimer t(timings_.backend_ms);
    updateBackend();
    keyframes_since_update_ = 0;
  }
}

BackendUpdateReport SlamPipeline::finish() {
  BackendUpdateReport report;
  {
    StageTimer t(timings_.backend_ms);
    report = backend_->update(true);
  }
  account(report);
  if (started_) timings_.wall_time_s = std::chrono::duration<double>(Clock::now() - start_).count();
  return report;
}

void SlamPipeline::logTracking(const std::optional<TrackingEvent>& event) const {
  // A recovery is as worth seeing as the loss (the default sink shows warnings only).
  if (event) logger_->warn(event->message);
}

PipelineTimings SlamPipeline::timings() const {
  PipelineTimings t = timings_;
  t.tracking = tracking_.stats();
  t.floors_found = floor_health_.found();
  t.floors_missing = floor_health_.missing();
  return t;
}

void SlamPipeline::updateBackend() {
  const BackendUpdateReport report = backend_->update();
  account(report);
  // The stored keyframes follow the corrections, as the queries do (mapToOdom above).
  if (loops_ && loop_search_in_map_) loops_->updatePoses(backend_->keyframeMapPoses());
}

void SlamPipeline::account(const BackendUpdateReport& report) {
  timings_.global_priors += report.global_priors;
  timings_.global_rejected += report.global_rejected;
  timings_.gnss_gated += report.gnss_gated;
  timings_.building_edges += report.building_edges;
  timings_.overlap_edges = report.overlap_edges;  // re-derived at every update
  timings_.shared_walls = report.shared_walls;
  timings_.floor_edges += report.floor_edges;
  timings_.floor_slope_changes += report.floor_slope_changes;
  if (report.heading_from_map) timings_.heading_from_map = report.heading_from_map;
  if (!report.optimized) return;
  ++timings_.updates;
  timings_.windowed_updates += report.window_start.has_value();
  timings_.loop_full_batches += report.full_batch_for_loop;
  timings_.slowest_update_ms = std::max(timings_.slowest_update_ms, report.total_ms);
  timings_.backend_stage_ms += report.stage_ms;
}

std::string SlamPipeline::scaleLine() const {
  const std::vector<double> scales = backend_->odometryScales();
  if (scales.empty()) return "";
  const auto [lo, hi] = std::minmax_element(scales.begin(), scales.end());
  char line[160];
  std::snprintf(line, sizeof(line), "odometry scale: %zu windows, %.4f .. %.4f\n", scales.size(),
                *lo, *hi);
  return line;
}

std::string SlamPipeline::timingTable() const {
  const PipelineTimings t = timings();
  const double scans = std::max<size_t>(1, t.scans);
  const double kfs = std::max<size_t>(1, t.keyframes);
  char buf[2048];
  std::snprintf(
      buf, sizeof(buf),
      "stage            total [ms]   per scan [ms]   per keyframe [ms]\n"
      "input (wait)     %10.0f   %13.2f   %17.2f\n"
      "prefilter%s %10.0f   %13.2f   %17.2f\n"
      "tracking         %10.0f   %13.2f   %17.2f\n"
      "wall points      %10.0f   %13.2f   %17.2f\n"
      "segments         %10.0f   %13.2f   %17.2f\n"
      "floor detection  %10.0f   %13.2f   %17.2f\n"
      "loop detection   %10.0f   %13.2f   %17.2f\n"
      "osm buffer       %10.0f   %13.2f   %17.2f\n"
      "graph back-end   %10.0f   %13.2f   %17.2f\n"
      "%zu scans, %zu keyframes, %zu loops in %.1f s: %.1f scans/s\n"
      "map priors: %zu global priors (%zu rejected), %zu robot-building edges, %zu "
      "overlap edges, %zu shared walls\n",
      t.input_ms, t.input_ms / scans, t.input_ms / kfs, t.prefilter_ahead ? " (ahead)" : "        ",
      t.prefilter_ms, t.prefilter_ms / scans, t.prefilter_ms / kfs, t.tracking_ms,
      t.tracking_ms / scans, t.tracking_ms / kfs, t.walls_ms, t.walls_ms / scans, t.walls_ms / kfs,
      t.segments_ms, t.segments_ms / scans, t.segments_ms / kfs, t.floor_ms, t.floor_ms / scans,
      t.floor_ms / kfs, t.loops_ms, t.loops_ms / scans, t.loops_ms / kfs, t.osm_ms,
      t.osm_ms / scans, t.osm_ms / kfs, t.backend_ms, t.backend_ms / scans, t.backend_ms / kfs,
      t.scans, t.keyframes, t.loops, t.wall_time_s, t.scansPerSecond(), t.global_priors,
      t.global_rejected, t.building_edges, t.overlap_edges, t.shared_walls);
  const TrackingStats& k = t.tracking;
  char track[512];
  std::snprintf(track, sizeof(track),
                "tracking: %zu matched, %zu failed matches, %zu rejected scans, %zu re-anchored "
                "keyframes; %zu lost track(s), %zu scans while lost, longest %.1f s without a "
                "keyframe; pre-tracker %.0f ms%s\n",
                k.matched, k.failed_matches, k.rejected_scans, k.reanchors, k.lost_events,
                k.scans_while_lost, k.longest_no_keyframe_s, t.pre_tracker_ms,
                k.lost_events ? "  <-- WARNING: part of the drive has no keyframe" : "");
  char updates[512];
  const BackendUpdateReport::StageMs& st = t.backend_stage_ms;
  std::snprintf(updates, sizeof(updates),
                "back-end: %zu updates (%zu windowed, %zu full batches for a loop), slowest %.0f "
                "ms; OSM matching %.0f ms, phase 1 %.0f ms, phase 2 %.0f ms, joint %.0f ms, "
                "overlaps %.0f ms\n",
                t.updates, t.windowed_updates, t.loop_full_batches, t.slowest_update_ms, st.osm,
                st.phase1, st.phase2, st.joint, st.overlaps);
  char floor[256];
  std::snprintf(floor, sizeof(floor),
                "floor: found on %zu keyframes, none on %zu; %zu plane edges, %zu slope changes\n",
                t.floors_found, t.floors_missing, t.floor_edges, t.floor_slope_changes);
  std::string heading;
  if (const auto& h = t.heading_from_map) {
    char line[320];
    std::snprintf(line, sizeof(line),
                  "initial heading from the OSM map (global matching) at keyframe %lu: pose "
                  "(%.2f, %.2f) m, yaw %.2f deg; trajectory rotated by %.2f deg, fitness %.1f\n",
                  static_cast<unsigned long>(h->keyframe_id), h->matched_pose.x, h->matched_pose.y,
                  h->matched_pose.theta * 180.0 / M_PI, h->rotation * 180.0 / M_PI, h->fitness);
    heading = line;
  }
  const std::string ahead =
      t.prefilter_ahead
          ? "prefilter ran ahead on the reading thread, overlapping the stages below: "
            "the stage times add up to more than the wall time\n"
          : "";
  std::string localization;
  if (handover_) {
    char line[320];
    std::snprintf(line, sizeof(line),
                  "localisation on the saved map: %.0f ms over %zu scans, %s; %zu keyframes "
                  "localised, not mapped\n",
                  t.localization_ms, localized_.size(),
                  handover_->mapping() ? "then handed over to mapping" : "never left the map",
                  handover_->keyframesLocalized());
    localization = line;
  }
  // The multi-cue tracker's health report says what it lacks next to GICP's (doc/multi_cue.md).
  const std::string multi_cue =
      usesSensorCloud()
          ? "tracker multi_cue: " + std::to_string(tracker_.trackerKeyframeCount()) +
                " tracker keyframes; next to gicp it lacks: match information on the odometry "
                "edges (they get the fitness model's middle), a multi-cue pre-tracker (the "
                "pre-tracker and its recovery guess register with GICP)\n"
          : "";
  return std::string(buf) + ahead + track + multi_cue + updates + floor + heading + localization +
         scaleLine();
}

namespace {

nlohmann::json cloudStoreJson(const CloudStoreStats& s) {
  constexpr double kMb = 1024.0 * 1024.0;
  return {{"clouds", s.clouds},
          {"resident", s.resident},
          {"on_disk", s.on_disk},
          {"resident_mb", s.resident_bytes / kMb},
          {"disk_mb", s.disk_bytes / kMb},
          {"pcl_mb", s.pcl_bytes / kMb},
          {"bytes_per_point", s.points ? double(s.encoded_bytes) / s.points : 0.0},
          {"write_errors", s.write_errors},
          {"read_errors", s.read_errors},
          {"last_error", s.last_error},
          {"ms",
           {{"encode", s.encode_ms},
            {"decode", s.decode_ms},
            {"write", s.write_ms},
            {"read", s.read_ms}}}};
}

}  // namespace

std::string SlamPipeline::timingJson() const {
  const PipelineTimings t = timings();
  const TrackingStats& k = t.tracking;
  nlohmann::json doc = {{"scans", t.scans},
                        {"keyframes", t.keyframes},
                        {"loops", t.loops},
                        {"wall_time_s", t.wall_time_s},
                        {"scans_per_second", t.scansPerSecond()},
                        {"map_priors",
                         {{"global_priors", t.global_priors},
                          {"global_rejected", t.global_rejected},
                          {"building_edges", t.building_edges},
                          {"overlap_edges", t.overlap_edges},
                          {"shared_walls", t.shared_walls}}},
                        {"gnss_fixes_gated", t.gnss_gated},
                        {"backend_updates",
                         {{"all", t.updates},
                          {"windowed", t.windowed_updates},
                          {"loop_full_batches", t.loop_full_batches},
                          {"slowest_ms", t.slowest_update_ms},
                          {"stage_ms",
                           {{"osm_matching", t.backend_stage_ms.osm},
                            {"phase1", t.backend_stage_ms.phase1},
                            {"phase2", t.backend_stage_ms.phase2},
                            {"joint", t.backend_stage_ms.joint},
                            {"overlaps", t.backend_stage_ms.overlaps}}}}},
                        {"floor",
                         {{"found", t.floors_found},
                          {"missing", t.floors_missing},
                          {"plane_edges", t.floor_edges},
                          {"slope_changes", t.floor_slope_changes}}},
                        {"ms",
                         {{"input", t.input_ms},
                          {"prefilter", t.prefilter_ms},
                          {"tracking", t.tracking_ms},
                          {"walls", t.walls_ms},
                          {"segments", t.segments_ms},
                          {"loops", t.loops_ms},
                          {"osm", t.osm_ms},
                          {"backend", t.backend_ms},
                          {"floor", t.floor_ms},
                          {"localization", t.localization_ms},
                          {"pre_tracker", t.pre_tracker_ms}}},
                        {"prefilter_ahead", t.prefilter_ahead},
                        {"tracking",
                         {{"scans", k.scans},
                          {"matched", k.matched},
                          {"failed_matches", k.failed_matches},
                          {"rejected_scans", k.rejected_scans},
                          {"lost_events", k.lost_events},
                          {"reanchors", k.reanchors},
                          {"scans_while_lost", k.scans_while_lost},
                          {"first_stamp", k.first_stamp},
                          {"last_stamp", k.last_stamp},
                          {"longest_no_keyframe_s", k.longest_no_keyframe_s}}}};
  doc["cloud_store"] = {{"backend", cloudStoreJson(backend_->cloudStoreStats())}};
  if (loops_) doc["cloud_store"]["loop_detection"] = cloudStoreJson(loops_->cloudStoreStats());
  if (const std::vector<double> scales = backend_->odometryScales(); !scales.empty())
    doc["odometry_scales"] = scales;
  if (const auto& h = t.heading_from_map) {
    doc["heading_from_map"] = {{"keyframe", h->keyframe_id},
                               {"x", h->matched_pose.x},
                               {"y", h->matched_pose.y},
                               {"yaw_deg", h->matched_pose.theta * 180.0 / M_PI},
                               {"rotation_deg", h->rotation * 180.0 / M_PI},
                               {"fitness", h->fitness}};
  }
  return doc.dump(2);
}

}  // namespace osm_graph_slam
