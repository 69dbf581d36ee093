#include "osm_graph_slam/slam/graph_backend.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <set>

#include <Eigen/Eigenvalues>

#include "backend_state.h"
#include "building_constraints.h"
#include "osm_association.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/information.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/osm/building_set.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// Inputs for keyframes this far beyond the newest one are not waited for (bounded memory).
constexpr uint64_t kMaxKeyframesAhead = 1000;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

Eigen::Isometry3d initialMapToOdom(const Eigen::Isometry3d& first_odom_pose,
                                   std::optional<double> yaw, const Eigen::Vector2d& position) {
  const double odom_yaw = planarPose(first_odom_pose).theta;
  Eigen::Isometry3d first =
      isometryFromPlanar(Pose2(0.0, 0.0, yaw ? *yaw - odom_yaw : 0.0)) * first_odom_pose;
  first.translation() << position.x(), position.y(), 0.0;
  return first * first_odom_pose.inverse();
}

const char* toString(OsmMode mode) {
  switch (mode) {
    case OsmMode::kPrior:
      return "prior";
    case OsmMode::kRigid:
      return "rigid";
    case OsmMode::kNonRigid:
      return "non_rigid";
  }
  return "?";
}

bool parseOsmMode(const std::string& text, OsmMode* mode) {
  for (OsmMode m : {OsmMode::kPrior, OsmMode::kRigid, OsmMode::kNonRigid}) {
    if (text == toString(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

Building BuildingState::corrected() const {
  Building b = prior;
  b.outline_enu = transformPolygon(local_outline, pose);
  b.reference_pose = pose;
  b.segments = polygonSegments(b.outline_enu);
  return b;
}

namespace {
// Edges between held vertices (a window's old part, fixed robots in phase 2) cannot change: left
// out, an update costs what its free part costs; the solution is the same.
GraphBackendParams withConstantEdgesSkipped(GraphBackendParams p) {
  p.schedule.optimizer.skip_constant_edges = true;
  return p;
}
}  // namespace

GraphBackend::GraphBackend(const GraphBackendParams& params, std::shared_ptr<const Logger> logger)
    : params_(withConstantEdgesSkipped(params)),
      logger_(logger ? std::move(logger) : std::make_shared<Logger>()),
      pending_(std::make_unique<BackendQueues>()),
      state_(std::make_unique<BackendState>()),
      osm_(std::make_unique<OsmAssociation>(params_.mode, params_.association, params_.osm_prior,
                                            params_.matcher, params_.schedule.joint_optimization,
                                            params_.odometry.odometry_attitude_std, *logger_)),
      constraints_(std::make_unique<BuildingConstraints>(params_.mode, params_.buildings,
                                                         params_.osm_prior, params_.matcher,
                                                         params_.schedule.optimizer)),
      clouds_(std::make_shared<CloudStore>(
          params_.cloud_store,
          [logger = logger_](LogLevel level, const std::string& m) { logger->log(level, m); })) {
  state_->heading_initialized = params_.initial_yaw_known;
  if (params_.initial_yaw_known) state_->initial_yaw = params_.initial_yaw;
}

GraphBackend::~GraphBackend() = default;

// ------------------------------------------------------------------------------------------------
// Inputs
// ------------------------------------------------------------------------------------------------

void GraphBackend::setOrigin(double lat, double lon, double alt) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (state_->origin) return;  // the first valid fix defines the map frame for good
  state_->origin.emplace(lat, lon, alt);
}

bool GraphBackend::hasOrigin() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->origin.has_value();
}

void GraphBackend::addKeyframe(KeyframeInput keyframe) {
  // Encoded here, on the caller's thread: keyframes that wait for a long update hold their
  // encodings (~70-90 kB), not their PCL clouds (~400 kB).
  StoredCloud cloud(clouds_, next_cloud_key_++, keyframe.cloud);
  keyframe.cloud.reset();
  std::lock_guard<std::mutex> lock(queue_mutex_);
  pending_->keyframes.push_back({std::move(keyframe), std::move(cloud)});
}

void GraphBackend::addLineSegments(uint64_t keyframe_id, std::vector<LineSegment2> segments) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  pending_->segments[keyframe_id] = std::move(segments);
}

void GraphBackend::addFloor(uint64_t keyframe_id, const Eigen::Vector4d& coeffs) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  pending_->floors[keyframe_id] = coeffs;
}

void GraphBackend::addBuildings(std::vector<Building> buildings,
                                const Eigen::Vector2d& query_center, double query_radius) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  pending_->buildings.push_back({std::move(buildings), query_center, query_radius});
}

void GraphBackend::addLoopClosure(const LoopClosureInput& loop) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  pending_->loops.push_back(loop);
}

size_t GraphBackend::pendingInputs() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return pending_->keyframes.size() + pending_->segments.size() + pending_->loops.size() +
         pending_->buildings.size() + pending_->floors.size();
}

CloudStoreStats GraphBackend::cloudStoreStats() const {
  return clouds_->stats();
}

// ------------------------------------------------------------------------------------------------
// Update
// ------------------------------------------------------------------------------------------------

BackendUpdateReport GraphBackend::update(bool force_optimize) {
  const auto t0 = Clock::now();
  BackendUpdateReport report;
  std::lock_guard<std::mutex> state_lock(state_mutex_);
  flushKeyframes(report);
  flushFloors(report);
  flushLoops(report);
  flushBuildings(report);
  if (params_.use_osm) processOsm(report);
  if (state_->dirty || force_optimize) {
    std::optional<uint64_t> window = force_optimize ? std::nullopt : windowStart();
    optimizePhases(report, window);
    if (window && newLoopDisagrees(*window)) {
      report.full_batch_for_loop = true;
      window.reset();
      optimizePhases(report, window);
    }
    state_->dirty = false;
    // Keyframes matched while the datum was elsewhere are matched again where it is now.
    if (params_.use_osm && osm_->reassociateAfterDatumMoved(*state_, report) > 0) {
      processOsm(report);
      optimizePhases(report, window, false);  // level 0 did not change: no phase 1
    }
    reportOdometryScale();
  }
  report.total_ms = msSince(t0);
  return report;
}

void GraphBackend::processOsm(BackendUpdateReport& report) {
  const auto t0 = Clock::now();
  osm_->process(*state_, report);
  report.stage_ms.osm += msSince(t0);
}

void GraphBackend::reportOdometryScale() {
  const BackendState& s = *state_;
  for (const auto& [session, windows] : s.sessions)
    for (const auto& [window, vid] : windows.scale_vertices) {
      const double scale = s.graph.vertexScale(vid).value_or(1.0);
      if (std::abs(scale - 1.0) <= kOdometryScaleWarning) continue;
      char text[320];
      std::snprintf(text, sizeof(text),
                    "the odometry's scale is estimated at %.4f over %.0f-%.0f m of path (session "
                    "%u): the scan matching is %.1f %% %s than the map and loops say (a LiDAR "
                    "range or vertical-angle calibration error?); logged once",
                    scale, window * params_.odometry.odometry_scale_window,
                    (window + 1) * params_.odometry.odometry_scale_window, session,
                    std::abs(scale - 1.0) * 100.0, scale > 1.0 ? "shorter" : "longer");
      logger_->warnOnce("odometry scale", text);
      return;
    }
}

void GraphBackend::flushKeyframes(BackendUpdateReport& report) {
  std::deque<PendingKeyframe> incoming;
  std::map<uint64_t, std::vector<LineSegment2>> segments;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    incoming.swap(pending_->keyframes);
    segments.swap(pending_->segments);
  }
  std::stable_sort(
      incoming.begin(), incoming.end(),
      [](const PendingKeyframe& a, const PendingKeyframe& b) { return a.input.id < b.input.id; });
  const size_t gated_before = state_->gnss_gated;
  for (auto& [in, cloud] : incoming) {
    if (!acceptable(in)) {
      cloud.erase();
      continue;
    }
    // A new session numbers its keyframes afresh: the ids between are not missing.
    if (state_->sessions.count(in.session))
      countMissing(in.id, report);
    else
      state_->keyframe_ids.restartAt(in.id);
    insertKeyframe(in, std::move(cloud));
    ++report.keyframes_added;
    state_->dirty = true;
  }
  report.gnss_gated += state_->gnss_gated - gated_before;
  // After the keyframes they name are in: a new session's ids are far ahead of the last one's.
  attachSegments(std::move(segments));
  dropOrphanSegments();
}

void GraphBackend::attachSegments(std::map<uint64_t, std::vector<LineSegment2>> segments) {
  BackendState& s = *state_;
  for (auto& [id, segs] : segments) {
    auto it = s.keyframes.find(id);
    const uint64_t newest = s.keyframes.empty() ? 0 : s.keyframes.rbegin()->first;
    if (it != s.keyframes.end()) {
      it->second.segments = std::move(segs);
    } else if (id <= newest + kMaxKeyframesAhead) {
      s.early_segments[id] = std::move(segs);
    } else {
      logger_->warnOnce("segments_ahead", "line segments for keyframe " + std::to_string(id) +
                                              ", far ahead of the newest keyframe; ignored");
    }
  }
}

bool GraphBackend::acceptable(const KeyframeInput& in) const {
  const BackendState& s = *state_;
  if (in.id >= static_cast<uint64_t>(kKeyframeIdLimit)) {
    logger_->warnOnce("kf_id", "keyframe id " + std::to_string(in.id) + " is too large; ignored");
    return false;
  }
  if (in.session >= static_cast<uint32_t>(kMaxSessions)) {
    logger_->warnOnce("kf_session", "keyframe " + std::to_string(in.id) + " of session " +
                                        std::to_string(in.session) + ": at most " +
                                        std::to_string(kMaxSessions) + " sessions; ignored");
    return false;
  }
  if (!s.keyframes.empty() && in.id <= s.keyframes.rbegin()->first) {
    logger_->warnOnce("kf_order", "keyframe " + std::to_string(in.id) +
                                      " is not newer than the last one (" +
                                      std::to_string(s.keyframes.rbegin()->first) +
                                      "); duplicate or out of order, ignored");
    return false;
  }
  return true;
}

void GraphBackend::countMissing(uint64_t id, BackendUpdateReport& report) {
  const uint64_t gap = state_->keyframe_ids.observe(id);
  if (gap == 0) return;
  report.keyframes_missing += gap;
  logger_->warnOnce("kf_missing",
                    "keyframes (" + state_->keyframe_ids.lastGap() +
                        ") never reached the back-end (an input queue overflowed or they were "
                        "dropped upstream); odometry bridges the gap. Counted in every report "
                        "from now on; logged once");
}

void GraphBackend::insertKeyframe(const KeyframeInput& in, StoredCloud cloud) {
  BackendState& s = *state_;
  KeyframeState kf;
  kf.id = in.id;
  kf.session = in.session;
  kf.stamp = in.stamp;
  kf.odom_pose = in.odom_pose;
  kf.accum_distance = in.accum_distance;
  kf.odom_fitness = in.odom_fitness;
  kf.odom_hessian = in.odom_hessian;
  kf.odom_prediction_error = in.odom_prediction_error;
  kf.reanchored = in.reanchored;
  kf.gravity_roll_pitch = in.gravity_roll_pitch;
  kf.gnss_position = in.gnss_position;
  kf.gnss_std = in.gnss_std;
  kf.gnss_altitude = in.gnss_altitude;
  kf.ins_yaw = in.ins_yaw;
  kf.cloud = std::move(cloud);
  if (in.floor) s.early_floors[in.id] = *in.floor;
  const auto session = s.sessions.find(in.session);
  if (s.keyframes.empty())
    anchorFirstKeyframe(in, kf);
  else if (session == s.sessions.end())
    anchorSessionStart(in, kf);
  else
    linkToPrevious(in, kf, s.keyframes.at(session->second.newest_keyframe));
  s.sessions[in.session].newest_keyframe = in.id;
  addKeyframePriors(in, kf);
  auto early = s.early_segments.find(in.id);
  if (early != s.early_segments.end()) {
    kf.segments = std::move(early->second);
    s.early_segments.erase(early);
  }
  s.latest_stamp = std::max(s.latest_stamp, in.stamp);
  s.keyframes.emplace(in.id, std::move(kf));
}

void GraphBackend::anchorFirstKeyframe(const KeyframeInput& in, KeyframeState& kf) {
  // The first keyframe sits at its GNSS position, else at the map origin (the first GPS fix),
  // with the known heading, or odometry's until the first global matching sets it.
  BackendState& s = *state_;
  const int vid = static_cast<int>(in.id);
  if (!in.gnss_position)
    logger_->info("first keyframe " + std::to_string(in.id) +
                  " has no GNSS position: fixed at the map origin (the first fix)");
  s.map_to_odom = initialMapToOdom(in.odom_pose, s.initial_yaw,
                                   in.gnss_position.value_or(Eigen::Vector2d::Zero()));
  kf.map_pose = s.map_to_odom * in.odom_pose;
  if (in.gravity_roll_pitch) {
    // Fixed with the IMU's roll and pitch, not odometry's (level at its start): otherwise the
    // fixed first vertex and the attitude priors of the others disagree by the slope.
    kf.map_pose =
        attitudeMeasurement(kf.map_pose, in.gravity_roll_pitch->x(), in.gravity_roll_pitch->y());
    s.map_to_odom = kf.map_pose * in.odom_pose.inverse();
  }
  // Known from the parameters or from setInitialHeading() (the nodelet: the IMU's heading).
  s.heading_known_at_start = s.initial_yaw.has_value();
  const bool gnss_held = gnssPriors() && in.gnss_position.has_value();
  const bool soft_anchor = s.heading_known_at_start && params_.gnss.anchor_std_xy > 0.0 &&
                           params_.gnss.anchor_std_yaw > 0.0;
  s.graph.addVertexSE3(vid, kf.map_pose, !gnss_held && !soft_anchor);
  if (!gnss_held && !soft_anchor) return;
  // Held where GNSS cannot say: height, attitude; x and y by the fixes (GNSS priors) or by the
  // anchor's deviation, the heading by the INS's.
  const double anchor_std =
      in.gnss_std && *in.gnss_std > 0.0 ? *in.gnss_std : params_.gnss.anchor_std_xy;
  const double xy_info = gnss_held ? 1e-6 : 1.0 / std::pow(anchor_std, 2);
  const double yaw_std = gnss_held ? params_.gnss.gnss_first_yaw_std : params_.gnss.anchor_std_yaw;
  Matrix6d info = Matrix6d::Zero();
  // The height is the first fix's altitude (the origin) unless the fixes' altitude is evidence.
  const double z_info = gnss_held && gnssAltitude() ? 1e-6 : 1.0 / (0.05 * 0.05);
  info.diagonal() << xy_info, xy_info, z_info, 1.0 / (0.01 * 0.01), 1.0 / (0.01 * 0.01),
      1.0 / std::pow(yaw_std, 2);
  s.graph.addPriorSE3(vid, kf.map_pose, info, EdgeOptions{0, {}});
}

void GraphBackend::anchorSessionStart(const KeyframeInput& in, KeyframeState& kf) {
  // A further drive starts at its own first fix with its own heading. Nothing ties it to the
  // drives before but the buildings they share and the loops between them, so it is left free
  // within its fix's deviation; with no fix it is held loosely where odometry and the heading
  // put it from the origin, until those join it.
  BackendState& s = *state_;
  const int vid = static_cast<int>(in.id);
  const auto yaw = s.session_start_yaw.find(in.session);
  const std::optional<double> start_yaw =
      yaw != s.session_start_yaw.end() ? std::optional<double>(yaw->second) : std::nullopt;
  if (!start_yaw || !in.gnss_position)
    logger_->warn("session " + std::to_string(in.session) + " starts (keyframe " +
                  std::to_string(in.id) + ") without " + (start_yaw ? "a GNSS fix" : "a heading") +
                  ": placed from the map origin until loops or buildings join it");
  kf.map_pose = initialMapToOdom(in.odom_pose, start_yaw,
                                 in.gnss_position.value_or(Eigen::Vector2d::Zero())) *
                in.odom_pose;
  if (in.gnss_altitude) kf.map_pose.translation().z() = *in.gnss_altitude;
  if (in.gravity_roll_pitch)
    kf.map_pose =
        attitudeMeasurement(kf.map_pose, in.gravity_roll_pitch->x(), in.gravity_roll_pitch->y());
  s.graph.addVertexSE3(vid, kf.map_pose);
  const bool gnss_held = gnssPriors() && in.gnss_position.has_value();
  // Held (deviation 1e3: free) by the fixes that follow; a fix without GNSS priors holds it with
  // its deviation; no fix leaves it free for the loops and buildings to place.
  // An unplaced session's start is a guess: held by nothing but its height and attitude until
  // its first loop places it (placeSession).
  const bool unplaced = s.unplaced_sessions.count(in.session) != 0;
  const double xy_std = !gnss_held && in.gnss_position && !unplaced
                            ? in.gnss_std.value_or(params_.gnss.anchor_std_xy)
                            : kUnheldStd;
  const double z_std = gnss_held && gnssAltitude() ? kUnheldStd : kSessionStartStdZ;
  const double yaw_std = start_yaw && !unplaced ? params_.gnss.gnss_first_yaw_std : M_PI;
  Matrix6d info = Matrix6d::Zero();
  info.diagonal() << 1.0 / (xy_std * xy_std), 1.0 / (xy_std * xy_std), 1.0 / (z_std * z_std),
      1.0 / (0.01 * 0.01), 1.0 / (0.01 * 0.01), 1.0 / (yaw_std * yaw_std);
  s.graph.addPriorSE3(vid, kf.map_pose, info, EdgeOptions{0, {}});
}

namespace {

/// The odometry edge's information: from the match's fitness, plus its Hessian (translation,
/// if weighted), loosened along the match's offset from the motion model's prediction (a motion
/// the model did not predict also distorted the deskewed scan).
Matrix6d odometryEdgeInformation(const KeyframeInput& in, const Eigen::Isometry3d& delta,
                                 const InformationParams& p) {
  Matrix6d info = odometryInformation(in.odom_fitness, p, delta.translation());
  // Zero (unknown) or non-finite (a corrupt message) inputs add nothing.
  if (p.hessian_weight > 0.0 && !in.odom_hessian.isZero() && in.odom_hessian.allFinite())
    info.topLeftCorner<3, 3>() +=
        p.hessian_weight * translationMarginal(registrationInformation(in.odom_hessian, delta));
  if (in.odom_prediction_error.allFinite())
    info.topLeftCorner<3, 3>() = withDeviationAlong(
        info.topLeftCorner<3, 3>(), p.prediction_error_scale * in.odom_prediction_error);
  return info;
}

}  // namespace

void GraphBackend::linkToPrevious(const KeyframeInput& in, KeyframeState& kf,
                                  const KeyframeState& prev) {
  BackendState& s = *state_;
  const int vid = static_cast<int>(in.id);
  const Eigen::Isometry3d delta = prev.odom_pose.inverse() * in.odom_pose;
  // A re-anchored step is a guess, not a measurement of the odometry's scale.
  const int scale = params_.odometry.odometry_scale_window > 0.0 && !in.reanchored
                        ? s.odometryScaleVertex(in.session, in.accum_distance, params_.odometry)
                        : -1;
  Eigen::Isometry3d scaled_delta = delta;
  if (scale >= 0) scaled_delta.translation() *= s.graph.vertexScale(scale).value_or(1.0);
  kf.map_pose = prev.map_pose * scaled_delta;
  s.graph.addVertexSE3(vid, kf.map_pose);
  Matrix6d info = odometryEdgeInformation(in, delta, params_.odometry.information);
  const bool jumped_back = in.stamp < prev.stamp;
  if (jumped_back)  // kept: the ids order the keyframes, the stamps may loop
    logger_->warn("keyframe " + std::to_string(in.id) + " is stamped " +
                  std::to_string(prev.stamp - in.stamp) + " s before keyframe " +
                  std::to_string(prev.id) + " (the time jumped back: a looped bag?); kept after " +
                  "it" + (in.reanchored ? " with a weak odometry edge" : "") +
                  ", the map so far is kept");
  if (in.reanchored) {
    info.setZero();
    info.diagonal().head<3>().setConstant(1.0 / std::pow(params_.odometry.reanchor_std_xyz, 2));
    info.diagonal().tail<3>().setConstant(1.0 / std::pow(params_.odometry.reanchor_std_rot, 2));
    if (!jumped_back)
      logger_->info("keyframe " + std::to_string(in.id) +
                    " was re-anchored after a lost track: weak odometry edge");
  }
  auto add = [&](const Matrix6d& information, int level) {
    const int from = static_cast<int>(prev.id);
    return scale >= 0 ? s.graph.addEdgeSE3Scaled(from, vid, scale, delta, information,
                                                 EdgeOptions{level, {}})
                      : s.graph.addEdgeSE3(from, vid, delta, information, EdgeOptions{level, {}});
  };
  std::vector<int> edges{add(info, 0)};
  // Levels >= 1 (the joint phase) see the odometry joint_odometry_weight times stiffer: the
  // buildings then correct the drift smoothly instead of kinking single keyframes.
  if (params_.schedule.joint_odometry_weight > 1.0)
    edges.push_back(add((params_.schedule.joint_odometry_weight - 1.0) * info, 1));
  if (jumped_back && in.reanchored) s.unplaced = BackendState::UnplacedPass{in.id, edges};
}

void GraphBackend::placeAfterRestart(const LoopClosureInput& loop) {
  BackendState& s = *state_;
  if (!s.unplaced || loop.from_id < s.unplaced->first_id || loop.to_id >= s.unplaced->first_id)
    return;
  const uint64_t first = s.unplaced->first_id;
  // The loop edge to -> from measures from's pose in to's frame.
  const Eigen::Isometry3d correction = s.keyframes.at(loop.to_id).map_pose * loop.relative_pose *
                                       s.keyframes.at(loop.from_id).map_pose.inverse();
  for (auto it = s.keyframes.lower_bound(first); it != s.keyframes.end(); ++it) {
    it->second.map_pose = correction * it->second.map_pose;
    s.graph.setVertexSE3(static_cast<int>(it->first), it->second.map_pose);
  }
  // The provisional link now holds where the new pass starts relative to the old one's end: a
  // robust loop kernel would otherwise lose against it (fault_injection.test: 20.9 m off).
  const auto first_kf = s.keyframes.find(first);
  const KeyframeState& prev = std::prev(first_kf)->second;
  const Eigen::Isometry3d link = prev.map_pose.inverse() * first_kf->second.map_pose;
  for (int edge_id : s.unplaced->link_edges) {
    const std::optional<EdgeInfo> e = s.graph.edge(edge_id);
    if (!e || !s.graph.removeEdge(edge_id)) continue;
    s.graph.addEdgeSE3(static_cast<int>(prev.id), static_cast<int>(first), link,
                       Matrix6d(e->information), EdgeOptions{e->level, e->kernel});
  }
  logger_->info("the pass after the time jumped back (keyframes from " + std::to_string(first) +
                ") placed by loop " + std::to_string(loop.from_id) + " -> " +
                std::to_string(loop.to_id) + ": moved " +
                std::to_string(correction.translation().norm()) + " m");
  s.unplaced.reset();
  s.dirty = true;
}

void GraphBackend::placeSession(const LoopClosureInput& loop) {
  BackendState& s = *state_;
  if (s.unplaced_sessions.empty()) return;
  const uint32_t from = s.sessionOf(loop.from_id), to = s.sessionOf(loop.to_id);
  const bool from_unplaced = s.unplaced_sessions.count(from) != 0;
  const bool to_unplaced = s.unplaced_sessions.count(to) != 0;
  if (from == to || from_unplaced == to_unplaced) return;
  // The loop edge to -> from measures from's pose in to's frame: the unplaced side moves so that
  // it holds exactly.
  const uint32_t moving = from_unplaced ? from : to;
  const Eigen::Isometry3d said = s.keyframes.at(loop.to_id).map_pose * loop.relative_pose;
  const Eigen::Isometry3d correction =
      from_unplaced ? said * s.keyframes.at(loop.from_id).map_pose.inverse()
                    : s.keyframes.at(loop.from_id).map_pose * loop.relative_pose.inverse() *
                          s.keyframes.at(loop.to_id).map_pose.inverse();
  for (auto& [id, kf] : s.keyframes) {
    if (kf.session != moving) continue;
    kf.map_pose = correction * kf.map_pose;
    s.graph.setVertexSE3(static_cast<int>(id), kf.map_pose);
  }
  s.unplaced_sessions.erase(moving);
  logger_->info("session " + std::to_string(moving) + " placed in the map by loop " +
                std::to_string(loop.from_id) + " -> " + std::to_string(loop.to_id) + ": moved " +
                std::to_string(correction.translation().norm()) + " m");
  s.dirty = true;
}

void GraphBackend::addKeyframePriors(const KeyframeInput& in, KeyframeState& kf) {
  BackendState& s = *state_;
  const int vid = static_cast<int>(in.id);
  if (gnssPriors() && in.gnss_position && gnssFixPassesGate(in, kf)) addGnssPrior(in);
  if (params_.gnss.ins_heading_std > 0.0 && in.ins_yaw) addInsHeadingChange(in);
  if (in.gravity_roll_pitch) {
    kf.has_attitude = true;
    s.graph.addPriorSE3(
        vid,
        attitudeMeasurement(kf.map_pose, in.gravity_roll_pitch->x(), in.gravity_roll_pitch->y()),
        attitudeInformation(params_.odometry.imu_attitude_std), EdgeOptions{0, {}});
  }
}

void GraphBackend::addGnssPrior(const KeyframeInput& in) {
  BackendState& s = *state_;
  const int vid = static_cast<int>(in.id);
  const bool altitude = gnssAltitude() && in.gnss_altitude.has_value();
  const Eigen::Vector3d fix(in.gnss_position->x(), in.gnss_position->y(),
                            altitude ? *in.gnss_altitude : 0.0);
  const double scale = gnssAccuracyScale(in);
  ++s.gnss_priors;  // from the second on the map's priors tighten (BackendState::gnssAnchored)
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();  // no altitude: z uninformed
  info(0, 0) = info(1, 1) = 1.0 / std::pow(params_.gnss.gnss_prior_std * scale, 2);
  if (altitude) info(2, 2) = 1.0 / std::pow(params_.gnss.gnss_altitude_std * scale, 2);
  const EdgeOptions options{
      0, kernelNamed(params_.gnss.gnss_prior_kernel, params_.gnss.gnss_prior_kernel_width)};
  if (params_.gnss.gnss_bias_std > 0.0)
    s.graph.addEdgeSE3PositionWithOffset(
        vid, s.gnssBiasVertex(in.session, in.stamp, params_.gnss, scale), fix, info, options);
  else if (altitude)
    s.graph.addPriorSE3XYZ(vid, fix, info, options);
  else
    s.graph.addPriorSE3XY(vid, fix.head<2>(), info.topLeftCorner<2, 2>(), options);
}

bool GraphBackend::gnssFixPassesGate(const KeyframeInput& in, const KeyframeState& kf) {
  BackendState& s = *state_;
  std::optional<double>& passed_at = s.sessions[in.session].gnss_passed_at;
  const GnssParams& g = params_.gnss;
  if (g.gnss_innovation_gate > 0.0 && passed_at) {
    const double reported = g.gnss_prior_std * gnssAccuracyScale(in);
    const double inherited = std::hypot(g.gnss_prior_std, g.gnss_bias_std);
    const double drift = g.gnss_gate_drift * std::max(0.0, in.accum_distance - *passed_at);
    const double deviation = std::sqrt(reported * reported + inherited * inherited + drift * drift);
    const double innovation = (*in.gnss_position - kf.map_pose.translation().head<2>()).norm();
    if (innovation > g.gnss_innovation_gate * deviation) {
      ++s.gnss_gated;
      logger_->warnOnce("gnss_gate",
                        "a GNSS fix " + std::to_string(innovation) + " m from keyframe " +
                            std::to_string(in.id) + "'s predicted position (gate " +
                            std::to_string(g.gnss_innovation_gate * deviation) +
                            " m) is not used: reflected or multipath fixes claim accuracy they "
                            "do not have; counted in the run report, logged once");
      return false;
    }
  }
  passed_at = in.accum_distance;
  return true;
}

double GraphBackend::gnssAccuracyScale(const KeyframeInput& in) const {
  // A receiver reports its whole error (white noise and bias together, as NavSatFix covariance
  // or OXTS pos_accuracy): an RTK fix then outweighs the map, a single-point one does not.
  const double modelled = std::hypot(params_.gnss.gnss_prior_std, params_.gnss.gnss_bias_std);
  if (!params_.gnss.gnss_reported_accuracy || !in.gnss_std || !(*in.gnss_std > 0.0) ||
      !std::isfinite(*in.gnss_std) || !(modelled > 0.0))
    return 1.0;
  return std::max(*in.gnss_std, params_.gnss.gnss_min_reported_std) / modelled;
}

void GraphBackend::addInsHeadingChange(const KeyframeInput& in) {
  // The INS's heading change since the keyframe ins_heading_span back bounds the odometry's
  // heading drift; its constant bias (and its yaw frame's offset from the map's) cancels, so the
  // absolute heading stays with the anchor and the map instead of being held at the INS's bias.
  BackendState& s = *state_;
  auto& headings = s.sessions[in.session].ins_headings;
  const auto back = headings.upper_bound(in.accum_distance - params_.gnss.ins_heading_span);
  if (back != headings.begin()) {
    const auto& [from_id, from_yaw] = std::prev(back)->second;
    const double info = 1.0 / (2.0 * params_.gnss.ins_heading_std * params_.gnss.ins_heading_std);
    s.graph.addEdgeSE3YawDifference(
        static_cast<int>(from_id), static_cast<int>(in.id), wrapAngle(*in.ins_yaw - from_yaw), info,
        EdgeOptions{0, RobustKernel::huber(params_.gnss.ins_heading_kernel_width)});
  }
  headings[in.accum_distance] = {in.id, *in.ins_yaw};
}

bool GraphBackend::gnssAltitude() const {
  return gnssPriors() && params_.gnss.gnss_altitude_std > 0.0;
}

void GraphBackend::dropOrphanSegments() {
  // Segments for keyframes that will never come (older than the newest keyframe) are dropped.
  BackendState& s = *state_;
  if (s.keyframes.empty()) return;
  const uint64_t newest = s.keyframes.rbegin()->first;
  for (auto it = s.early_segments.begin(); it != s.early_segments.end();) {
    if (it->first < newest) {
      logger_->warnOnce("segments_unknown", "line segments for unknown keyframe " +
                                                std::to_string(it->first) + " dropped");
      it = s.early_segments.erase(it);
    } else {
      ++it;
    }
  }
}

void GraphBackend::flushLoops(BackendUpdateReport& report) {
  BackendState& s = *state_;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    for (auto& l : pending_->loops) s.early_loops.push_back(l);
    pending_->loops.clear();
  }
  const uint64_t newest = s.keyframes.empty() ? 0 : s.keyframes.rbegin()->first;
  std::deque<LoopClosureInput> keep;
  for (const auto& loop : s.early_loops) {
    const bool have_from = s.keyframes.count(loop.from_id) != 0;
    const bool have_to = s.keyframes.count(loop.to_id) != 0;
    if (!have_from && (s.keyframes.empty() || loop.from_id > newest)) {
      if (loop.from_id <= newest + kMaxKeyframesAhead) {
        keep.push_back(loop);  // its keyframe is still on the way
        continue;
      }
      logger_->warnOnce("loop_ahead", "loop closure from keyframe " + std::to_string(loop.from_id) +
                                          ", far ahead of the newest keyframe; ignored");
      ++report.loops_rejected;
      continue;
    }
    if (!have_from || !have_to || loop.from_id == loop.to_id) {
      logger_->warnOnce("loop_unknown", "loop closure " + std::to_string(loop.from_id) + " -> " +
                                            std::to_string(loop.to_id) +
                                            " names an unknown keyframe; ignored");
      ++report.loops_rejected;
      continue;
    }
    placeAfterRestart(loop);
    placeSession(loop);
    s.graph.addEdgeSE3(
        static_cast<int>(loop.to_id), static_cast<int>(loop.from_id), loop.relative_pose,
        loop.information,
        EdgeOptions{0, kernelNamed(params_.loops.loop_kernel, params_.loops.loop_kernel_width)});
    s.loops.push_back(loop);
    ++report.loops_added;
    s.dirty = true;
  }
  s.early_loops.swap(keep);
}

void GraphBackend::flushBuildings(BackendUpdateReport& report) {
  std::deque<BackendQueues::BuildingBatch> batches;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    batches.swap(pending_->buildings);
  }
  // Without OSM (the baseline) buildings are neither matched nor saved: save_map would otherwise
  // write the uncorrected prior as if it were a result.
  if (!params_.use_osm) return;
  BackendState& s = *state_;
  for (auto& batch : batches) {
    s.coverage.emplace_back(batch.center, batch.radius);
    for (auto& b : batch.buildings) {
      if (b.outline_enu.size() < 3 || s.buildings.count(b.id)) continue;
      BuildingState state;
      state.prior = b;
      state.pose = s.predictedPose(state, params_.osm_prior);
      state.local_outline = transformPolygon(b.outline_enu, b.reference_pose.inverse());
      s.buildings.emplace(state.prior.id, std::move(state));
      ++report.buildings_added;
    }
  }
}

bool GraphBackend::gnssPriors() const {
  // With the heading still unknown at the first keyframe it must stay fixed: global matching
  // rotates the trajectory about it.
  return params_.gnss.gnss_prior_std > 0.0 && state_->heading_known_at_start;
}

void GraphBackend::flushFloors(BackendUpdateReport& report) {
  std::map<uint64_t, Eigen::Vector4d> floors;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    floors.swap(pending_->floors);
  }
  BackendState& s = *state_;
  for (const auto& [id, coeffs] : floors) s.early_floors[id] = coeffs;
  const uint64_t newest = s.keyframes.empty() ? 0 : s.keyframes.rbegin()->first;
  for (auto it = s.early_floors.begin(); it != s.early_floors.end();) {
    auto kf = s.keyframes.find(it->first);
    if (kf != s.keyframes.end()) {
      kf->second.floor = it->second;
      linkFloor(kf->second, report);
    } else if (it->first > newest || s.keyframes.empty()) {
      break;  // its keyframe has not arrived yet (ids ascend)
    } else {
      logger_->warnOnce("floor_unknown",
                        "floor for unknown keyframe " + std::to_string(it->first) + " dropped");
    }
    it = s.early_floors.erase(it);
  }
}

void GraphBackend::linkFloor(KeyframeState& kf, BackendUpdateReport& report) {
  BackendState& s = *state_;
  std::optional<uint64_t>& last = s.sessions[kf.session].last_floor_keyframe;
  const std::optional<uint64_t> prev_id = last;
  if (prev_id && *prev_id >= kf.id) return;  // out of order: keep the newer chain
  last = kf.id;
  if (!params_.floor.floor_edges || !prev_id) return;
  const KeyframeState& prev = s.keyframes.at(*prev_id);
  // Far apart along the path, or stamped before the previous one (the time jumped back: a looped
  // bag starts elsewhere): not the same stretch of ground.
  if (kf.accum_distance - prev.accum_distance > params_.floor.floor_max_link_distance ||
      kf.stamp < prev.stamp) {
    ++report.floor_gaps;
    return;
  }
  // The same ground only if the floors agree in the map frame (odometry links the two poses).
  const Eigen::Vector3d n_prev = prev.map_pose.linear() * prev.floor->head<3>();
  const Eigen::Vector3d n_this = kf.map_pose.linear() * kf.floor->head<3>();
  const double bend =
      std::acos(std::clamp(n_prev.normalized().dot(n_this.normalized()), -1.0, 1.0));
  if (bend > params_.floor.floor_slope_change_deg * M_PI / 180.0) {
    ++report.floor_slope_changes;
    logger_->info("keyframe " + std::to_string(kf.id) + ": the floor bends by " +
                  std::to_string(bend * 180.0 / M_PI) + " deg (a change of slope): not tied to " +
                  "keyframe " + std::to_string(prev.id));
    return;
  }
  // Both floors are measured: the difference carries twice the variance of one.
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  info(0, 0) = info(1, 1) = 0.5 / std::pow(params_.floor.floor_normal_std, 2);
  // With gravity from the IMU on both, the floor only says the height: a floor fit tilts with
  // the road's camber and curvature, gravity does not (sim: tilt error 0.038 -> 0.056 deg).
  if (prev.gravity_roll_pitch && kf.gravity_roll_pitch && !params_.floor.floor_attitude_with_imu)
    info(0, 0) = info(1, 1) = 1e-9;
  info(2, 2) = 0.5 / std::pow(params_.floor.floor_distance_std, 2);
  if (s.graph.addEdgeSE3PlanePair(
          static_cast<int>(prev.id), static_cast<int>(kf.id), *prev.floor, *kf.floor, info,
          EdgeOptions{0, RobustKernel::huber(params_.floor.floor_kernel_width)}) < 0) {
    logger_->warnOnce("floor_edge", "floor edge rejected: " + s.graph.lastError());
    return;
  }
  s.keyframes.at(*prev_id).floor_tied = kf.floor_tied = true;
  ++report.floor_edges;
  s.dirty = true;
}

std::optional<uint64_t> GraphBackend::windowStart() const {
  const auto& keyframes = state_->keyframes;
  if (params_.schedule.optimization_window <= 0 ||
      keyframes.size() <= static_cast<size_t>(params_.schedule.optimization_window))
    return std::nullopt;
  return std::prev(keyframes.end(), params_.schedule.optimization_window)->first;
}

bool GraphBackend::newLoopDisagrees(uint64_t window_start) {
  BackendState& s = *state_;
  bool disagrees = false;
  for (size_t i = s.loops_checked_by_window; i < s.loops.size(); ++i) {
    const LoopClosureInput& loop = s.loops[i];
    if (std::min(loop.from_id, loop.to_id) >= window_start ||
        params_.schedule.window_loop_chi2 <= 0.0)
      continue;
    // The loop edge's error (as the SE3 edge measures it) at the windowed solution.
    const Eigen::Isometry3d estimate =
        s.keyframes.at(loop.to_id).map_pose.inverse() * s.keyframes.at(loop.from_id).map_pose;
    const Eigen::Isometry3d diff = loop.relative_pose.inverse() * estimate;
    Eigen::Quaterniond q(diff.linear());
    if (q.w() < 0.0) q.coeffs() *= -1.0;
    Vector6d e;
    e << diff.translation(), q.vec();
    disagrees |= e.dot(loop.information * e) > params_.schedule.window_loop_chi2;
  }
  s.loops_checked_by_window = s.loops.size();
  return disagrees;
}

void GraphBackend::optimizePhases(BackendUpdateReport& report, std::optional<uint64_t> window_start,
                                  bool phase1) {
  BackendState& s = *state_;
  report.window_start = window_start;
  runPhases(report,
            window_start ? s.holdOutsideWindow(*window_start, params_.odometry, params_.gnss)
                         : std::vector<int>{},
            phase1);
}

void GraphBackend::runPhases(BackendUpdateReport& report, const std::vector<int>& held,
                             bool phase1) {
  BackendState& s = *state_;
  const OptimizerOptions& options = params_.schedule.optimizer;
  // One optimisation at `level` into `result`, its time added to the update's stage.
  auto solve = [&](int level, OptimizationResult& result, double& stage_ms) {
    result = s.graph.optimize(level, options);
    stage_ms += result.time_ms;
  };

  // Phase 1 (level 0): robot poses from odometry, loops and global priors; buildings untouched.
  if (phase1) {
    solve(0, report.phase1, report.stage_ms.phase1);
    s.readRobotPoses();
  }
  report.optimized = true;

  bool have_buildings = false;
  for (const auto& [bid, b] : s.buildings) have_buildings |= b.vertex_id >= 0;
  if (!have_buildings || params_.mode == OsmMode::kPrior) {
    s.release(held, params_.osm_prior);
    updateMapToOdom();
    return;
  }
  // Phase 2 (level 1): robot vertices fixed, buildings move to satisfy their constraints.
  constraints_->removeOverlapEdges(s);  // re-derived below
  if (params_.buildings.use_shared_walls && params_.mode == OsmMode::kNonRigid)
    constraints_->addSharedWallEdges(s, report);
  const std::vector<int> unfix = s.fixRobots();
  solve(1, report.phase2, report.stage_ms.phase2);
  s.readBuildingPoses(params_.osm_prior);
  if (params_.buildings.building_edge_gate_chi2 > 0.0 &&
      constraints_->gateBuildingEdges(s, report) > 0) {
    solve(1, report.phase2, report.stage_ms.phase2);
    s.readBuildingPoses(params_.osm_prior);
  }
  if (params_.schedule.joint_optimization) {
    // Phase 3 (level 1): everything together, from phase 2's buildings.
    for (int vid : unfix) s.graph.setFixed(vid, false);
    solve(1, report.joint, report.stage_ms.joint);
    s.readRobotPoses();
    s.readBuildingPoses(params_.osm_prior);
    s.fixRobots();
  }
  if (params_.buildings.resolve_overlaps) {
    const auto t0 = Clock::now();
    constraints_->resolveOverlaps(s, report);
    report.stage_ms.overlaps += msSince(t0);
  }
  for (int vid : unfix) s.graph.setFixed(vid, false);
  s.release(held, params_.osm_prior);
  updateMapToOdom();
}

void GraphBackend::shiftMapToFixes() {
  // The coarse level of the tile solve: a translation of everything moves no relative edge
  // (odometry, loops, robot<->building, buildings from the datum), only the GNSS fixes' and the
  // datum prior's residuals. Tiles held by their neighbours hardly move together (block
  // Gauss-Seidel's slow mode: 0.36 m off the joint solve after converged sweeps, two drives);
  // the fixes' residuals give that translation's step.
  BackendState& s = *state_;
  if (!gnssPriors()) return;
  std::vector<double> dx, dy;
  for (const auto& [id, kf] : s.keyframes) {
    if (!kf.gnss_position) continue;
    Eigen::Vector2d predicted = kf.map_pose.translation().head<2>();
    if (params_.gnss.gnss_bias_std > 0.0) {
      const BackendState::Session& session = s.sessions[kf.session];
      const auto bias = session.gnss_bias_vertices.find(
          BackendState::gnssBiasWindow(session, kf.stamp, params_.gnss));
      if (bias != session.gnss_bias_vertices.end())
        predicted +=
            s.graph.vertexPointXYZ(bias->second).value_or(Eigen::Vector3d::Zero()).head<2>();
    }
    dx.push_back(kf.gnss_position->x() - predicted.x());
    dy.push_back(kf.gnss_position->y() - predicted.y());
  }
  if (dx.empty()) return;
  // Their median per axis: neither the fixes' mean nor their kernel's reweighted mean is the
  // joint solve's step (the biases share the translation), and the median came nearest to it
  // (two drives, 400 m tiles: mean of keyframes 0.11 m off the joint solve; reweighted 0.22 m;
  // no coarse step 0.36 m).
  auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const Eigen::Vector2d shift(median(dx), median(dy));
  for (auto& [id, kf] : s.keyframes) {
    if (s.graph.isFixed(static_cast<int>(id))) continue;
    kf.map_pose.translation().head<2>() += shift;
    s.graph.setVertexSE3(static_cast<int>(id), kf.map_pose);
  }
  for (auto& [bid, b] : s.buildings) {
    if (b.vertex_id < 0 || s.graph.isFixed(b.vertex_id)) continue;
    b.pose = Pose2(b.pose.x + shift.x(), b.pose.y + shift.y(), b.pose.theta);
    s.graph.setVertexSE2(b.vertex_id, b.pose);
  }
  if (const auto datum = s.graph.vertexSE2(kOsmDatumVertex))
    s.graph.setVertexSE2(kOsmDatumVertex,
                         Pose2(datum->x + shift.x(), datum->y + shift.y(), datum->theta));
}

TileSolveReport GraphBackend::optimizeInTiles(const TileSolveParams& params) {
  const auto t0 = Clock::now();
  update(false);  // queued inputs into the graph (a windowed update at most)
  std::lock_guard<std::mutex> lock(state_mutex_);
  BackendState& s = *state_;
  TileSolveReport out;
  const double size = std::max(params.tile_size, 1.0);
  using Tile = std::pair<int64_t, int64_t>;
  // The grid starts at the map's south-west corner: a map smaller than a tile is one tile.
  Eigen::Vector2d corner = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  for (const auto& [id, kf] : s.keyframes)
    corner = corner.cwiseMin(kf.map_pose.translation().head<2>());
  for (const auto& [bid, b] : s.buildings) corner = corner.cwiseMin(b.pose.translation());
  auto tileOf = [size, corner](const Eigen::Vector2d& p) {
    return Tile{static_cast<int64_t>(std::floor((p.x() - corner.x()) / size)),
                static_cast<int64_t>(std::floor((p.y() - corner.y()) / size))};
  };
  // Tiles are fixed once, from where the keyframes and buildings are now: a vertex that moves
  // across a border during the sweeps stays in its tile.
  std::map<Tile, std::pair<std::set<uint64_t>, std::set<int64_t>>> tiles;
  for (const auto& [id, kf] : s.keyframes)
    tiles[tileOf(kf.map_pose.translation().head<2>())].first.insert(id);
  for (const auto& [bid, b] : s.buildings)
    if (b.vertex_id >= 0) tiles[tileOf(b.pose.translation())].second.insert(bid);
  out.tiles = tiles.size();
  std::vector<const Tile*> order;
  for (int colour : {0, 1})
    for (const auto& [tile, members] : tiles)
      if (((tile.first + tile.second) % 2 + 2) % 2 == colour) order.push_back(&tile);
  for (const auto& [tile, members] : tiles)
    out.largest_tile_keyframes = std::max(out.largest_tile_keyframes, members.first.size());

  auto positions = [&s] {
    std::vector<Eigen::Vector2d> p;
    for (const auto& [id, kf] : s.keyframes) p.push_back(kf.map_pose.translation().head<2>());
    for (const auto& [bid, b] : s.buildings) p.push_back(b.pose.translation());
    return p;
  };
  for (out.sweeps = 1; out.sweeps <= params.max_sweeps; ++out.sweeps) {
    const std::vector<Eigen::Vector2d> before = positions();
    for (const Tile* tile : order) {
      const auto t_tile = Clock::now();
      const auto& [free_keyframes, free_buildings] = tiles.at(*tile);
      BackendUpdateReport report;
      runPhases(report,
                s.holdOutsideTile(free_keyframes, free_buildings, params_.odometry, params_.gnss),
                true);
      out.slowest_tile_ms = std::max(out.slowest_tile_ms, msSince(t_tile));
    }
    shiftMapToFixes();
    const std::vector<Eigen::Vector2d> after = positions();
    out.last_sweep_max_move = 0.0;
    for (size_t i = 0; i < before.size(); ++i)
      out.last_sweep_max_move = std::max(out.last_sweep_max_move, (after[i] - before[i]).norm());
    if (out.last_sweep_max_move <= params.tolerance) break;
  }
  out.sweeps = std::min(out.sweeps, params.max_sweeps);
  s.dirty = false;
  out.total_ms = msSince(t0);
  return out;
}

void GraphBackend::setInitialHeading(double yaw) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  BackendState& s = *state_;
  if (s.heading_initialized) return;
  s.heading_initialized = true;
  s.initial_yaw = yaw;
  if (s.keyframes.empty()) return;  // applied when the first keyframe arrives
  s.rotateTrajectory(wrapAngle(yaw - planarPose(s.keyframes.begin()->second.map_pose).theta));
  s.dirty = true;
  logger_->info("initial heading set to " + std::to_string(yaw * 180.0 / M_PI) + " deg");
}

void GraphBackend::setSessionHeading(uint32_t session, double yaw) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  state_->session_start_yaw[session] = yaw;
}

void GraphBackend::setSessionUnplaced(uint32_t session) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  state_->unplaced_sessions.insert(session);
}

bool GraphBackend::sessionPlaced(uint32_t session) const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->unplaced_sessions.count(session) == 0;
}

size_t GraphBackend::holdKeyframesAt(const std::map<uint64_t, Eigen::Isometry3d>& poses) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  BackendState& s = *state_;
  size_t held = 0;
  for (const auto& [id, pose] : poses) {
    const auto kf = s.keyframes.find(id);
    if (kf == s.keyframes.end()) continue;
    kf->second.map_pose = pose;
    s.graph.setVertexSE3(static_cast<int>(id), pose);
    s.graph.setFixed(static_cast<int>(id), true);
    ++held;
  }
  s.dirty = true;
  updateMapToOdom();
  return held;
}

void GraphBackend::updateMapToOdom() {
  BackendState& s = *state_;
  if (s.keyframes.empty()) return;
  const KeyframeState& last = s.keyframes.rbegin()->second;
  s.map_to_odom = last.map_pose * last.odom_pose.inverse();
}

// ------------------------------------------------------------------------------------------------
// Outputs
// ------------------------------------------------------------------------------------------------

std::vector<KeyframeState> GraphBackend::keyframes() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<KeyframeState> out;
  out.reserve(state_->keyframes.size());
  for (const auto& [id, kf] : state_->keyframes) out.push_back(kf);
  return out;
}

size_t GraphBackend::missingKeyframes() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->keyframe_ids.missing();
}

size_t GraphBackend::numKeyframes() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->keyframes.size();
}

std::optional<KeyframeState> GraphBackend::latestKeyframe() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (state_->keyframes.empty()) return std::nullopt;
  return state_->keyframes.rbegin()->second;
}

Eigen::Isometry3d GraphBackend::mapToOdom() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->map_to_odom;
}

Trajectory GraphBackend::trajectory() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  Trajectory t;
  for (const auto& [id, kf] : state_->keyframes) t.push_back({kf.stamp, kf.map_pose});
  return t;
}

std::vector<std::pair<uint64_t, Eigen::Isometry3d>> GraphBackend::keyframeMapPoses() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<std::pair<uint64_t, Eigen::Isometry3d>> out;
  out.reserve(state_->keyframes.size());
  for (const auto& [id, kf] : state_->keyframes) out.emplace_back(id, kf.map_pose);
  return out;
}

Trajectory GraphBackend::odomTrajectory() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  Trajectory t;
  for (const auto& [id, kf] : state_->keyframes) t.push_back({kf.stamp, kf.odom_pose});
  return t;
}

std::vector<BuildingObservation> GraphBackend::buildingObservations() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<BuildingObservation> out;
  for (const auto& e : state_->building_edges)
    out.push_back({e.keyframe, e.building, e.z, e.information});
  return out;
}

std::optional<Pose2> GraphBackend::osmDatum() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->graph.vertexSE2(kOsmDatumVertex);
}

std::vector<double> GraphBackend::odometryScales() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<double> out;
  for (const auto& [session, windows] : state_->sessions)
    for (const auto& [window, vid] : windows.scale_vertices)
      out.push_back(state_->graph.vertexScale(vid).value_or(1.0));
  return out;
}

std::vector<BuildingState> GraphBackend::buildings() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<BuildingState> out;
  for (const auto& [id, b] : state_->buildings) out.push_back(b);
  return out;
}

std::vector<Building> GraphBackend::correctedBuildings() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::map<int64_t, std::set<uint32_t>> sessions;
  std::map<int64_t, std::set<uint64_t>> keyframes;
  for (const auto& e : state_->building_edges) {
    sessions[e.building].insert(state_->sessionOf(e.keyframe));
    keyframes[e.building].insert(e.keyframe);
  }
  std::vector<Building> out;
  for (const auto& [id, b] : state_->buildings) {
    Building c = b.corrected();
    c.tags[kObservationsTag] = std::to_string(b.observations);
    c.tags[kKeyframesTag] = std::to_string(keyframes.count(id) ? keyframes.at(id).size() : 0);
    c.tags[kSessionsTag] = std::to_string(sessions.count(id) ? sessions.at(id).size() : 0);
    char text[32];
    if (b.sigma_xy) {
      std::snprintf(text, sizeof(text), "%.3f", *b.sigma_xy);
      c.tags[kSigmaXyTag] = text;
    }
    if (b.sigma_theta) {
      std::snprintf(text, sizeof(text), "%.3f", *b.sigma_theta * 180.0 / M_PI);
      c.tags[kSigmaThetaTag] = text;
    }
    if (state_->origin) {
      c.outline_geo.clear();
      for (const auto& v : c.outline_enu) c.outline_geo.push_back(state_->origin->toGeoPoint(v));
    }
    out.push_back(std::move(c));
  }
  return out;
}

bool GraphBackend::estimateBuildingUncertainty() {
  std::lock_guard<std::mutex> lock(state_mutex_);
  BackendState& s = *state_;
  std::vector<int> vertices;
  for (const auto& [id, b] : s.buildings)
    if (b.vertex_id >= 0 && b.observations > 0) vertices.push_back(b.vertex_id);
  // Given the trajectory (robots held): the buildings' own evidence, in a problem of small
  // blocks. The marginal over the whole graph costs a sparse QR of every keyframe and loop:
  // 2.8 s at 16 drives once, over 10 min with another loop set (the fill-in).
  const std::vector<int> held = s.fixRobots();
  std::map<int, Eigen::MatrixXd> covariances;
  const bool ok = s.graph.marginalCovariances(vertices, &covariances);
  for (int vid : held) s.graph.setFixed(vid, false);
  if (!ok) {
    logger_->warn("the buildings' deviations could not be estimated: " + s.graph.lastError());
    return false;
  }
  for (auto& [id, b] : s.buildings) {
    const auto c = covariances.find(b.vertex_id);
    if (b.vertex_id < 0 || c == covariances.end()) continue;
    const Eigen::Matrix2d xy = c->second.topLeftCorner<2, 2>();
    b.sigma_xy = std::sqrt(
        std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(xy).eigenvalues().maxCoeff()));
    b.sigma_theta = std::sqrt(std::max(0.0, c->second(2, 2)));
  }
  return true;
}

PoseGraph GraphBackend::graphSnapshot() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->graph;
}

std::vector<LoopClosureInput> GraphBackend::loopClosures() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->loops;
}

std::optional<EnuConverter> GraphBackend::origin() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->origin;
}

std::optional<double> GraphBackend::startHeading() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return state_->initial_yaw;
}

}  // namespace osm_graph_slam
