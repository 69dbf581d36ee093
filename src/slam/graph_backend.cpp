#include "osm_graph_slam/slam/graph_backend.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/eval/slam_evaluation.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/building_contacts.h"
#include "osm_graph_slam/slam/information.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// Inputs for keyframes this far beyond the newest one are not waited for (bounded memory).
constexpr uint64_t kMaxKeyframesAhead = 1000;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

RobustKernel kernelNamed(const std::string& name, double width) {
  if (name == "huber") return RobustKernel::huber(width);
  if (name == "cauchy") return RobustKernel::cauchy(width);
  return RobustKernel::none();
}

/// The separated pose moved `clearance` further along the separating translation. A flush target
/// leaves no room: when a building is separated from two neighbours at once, the optimiser
/// compromises between the hard edges and the outlines keep touching by a few millimetres.
Pose2 withClearance(const Pose2& separated, const Pose2& before, double clearance) {
  const Eigen::Vector2d move = separated.translation() - before.translation();
  if (clearance <= 0.0 || move.norm() < 1e-6) return separated;
  const Eigen::Vector2d t = separated.translation() + clearance * move.normalized();
  return {t.x(), t.y(), separated.theta};
}

/// Information of a 2D match (translation in map axes) re-expressed in the axes of an edge whose
/// error is measured in a frame rotated by `frame_yaw` (the g2o SE2 error convention).
Eigen::Matrix3d rotateInformation(const Eigen::Matrix3d& info_map, double frame_yaw) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  R.topLeftCorner<2, 2>() = Pose2(0, 0, frame_yaw).rotation();
  return R.transpose() * info_map * R;
}

/// The matcher's information (§3.3.5: by feature type, scaled by fitness) rescaled so that the
/// best possible match (edge feature, full fitness) has the given standard deviations.
Eigen::Matrix3d scaledInformation(const Eigen::Matrix3d& matcher_info, double std_xy,
                                  double std_theta, const LineMatcherParams& m) {
  Eigen::Matrix3d info = matcher_info;
  const double sxy = 1.0 / (std_xy * std_xy * m.edge_information_xy);
  const double sth = 1.0 / (std_theta * std_theta * m.edge_information_theta);
  info.topLeftCorner<2, 2>() *= sxy;
  info(2, 2) *= sth;
  info.topRightCorner<2, 1>() *= std::sqrt(sxy * sth);
  info.bottomLeftCorner<1, 2>() *= std::sqrt(sxy * sth);
  return info;
}

/// A unary SE3 edge that constrains only roll and pitch (the x/y components of the rotation
/// error in the measurement frame, whose yaw is the current estimate's).
Eigen::Isometry3d attitudeMeasurement(const Eigen::Isometry3d& pose, double roll, double pitch) {
  const double yaw = planarPose(pose).theta;
  Eigen::Isometry3d z = Eigen::Isometry3d::Identity();
  z.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  z.translation() = pose.translation();
  return z;
}

Matrix6d attitudeInformation(double std_rad) {
  Matrix6d info = Matrix6d::Identity() * 1e-9;  // positive definite; effectively unconstrained
  info(3, 3) = info(4, 4) = 1.0 / (std_rad * std_rad);
  return info;
}

Eigen::Vector2d rollPitch(const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d r = pose.rotation();
  return {std::atan2(r(2, 1), r(2, 2)), std::asin(-std::clamp(r(2, 0), -1.0, 1.0))};
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

struct GraphBackend::Pending {
  std::deque<KeyframeInput> keyframes;
  std::map<uint64_t, std::vector<LineSegment2>> segments;
  std::map<uint64_t, Eigen::Vector4d> floors;
  std::deque<LoopClosureInput> loops;
  struct BuildingBatch {
    std::vector<Building> buildings;
    Eigen::Vector2d center;
    double radius;
  };
  std::deque<BuildingBatch> buildings;
};

struct GraphBackend::State {
  PoseGraph graph;
  std::map<uint64_t, KeyframeState> keyframes;
  std::map<int64_t, BuildingState> buildings;
  std::map<uint64_t, std::vector<LineSegment2>> early_segments;  ///< keyframe not yet inserted
  std::map<uint64_t, Eigen::Vector4d> early_floors;              ///< keyframe not yet inserted
  std::optional<uint64_t> last_floor_keyframe;               ///< the newest keyframe with a floor
  std::deque<LoopClosureInput> early_loops;                  ///< current keyframe not yet in
  std::vector<std::pair<Eigen::Vector2d, double>> coverage;  ///< answered OSM queries
  std::optional<EnuConverter> origin;
  Eigen::Isometry3d map_to_odom = Eigen::Isometry3d::Identity();
  bool heading_initialized = false;
  std::optional<double> initial_yaw;  ///< known ENU yaw of the first keyframe
  int next_building_vertex = kBuildingVertexBase;
  std::vector<int> overlap_edges;
  struct SharedWall {
    BuildingContact contact;  ///< ENU prior geometry
    bool tied = false;        ///< its two wall-end-on-wall edges are in the graph
  };
  std::map<std::pair<int64_t, int64_t>, SharedWall> shared_walls;
  size_t shared_walls_searched = 0;  ///< number of buildings at the last search
  struct BuildingEdge {
    int edge_id;
    uint64_t keyframe;
    int64_t building;
    Pose2 z;
    Eigen::Matrix3d information;
  };
  std::vector<BuildingEdge> building_edges;  ///< robot<->building edges still in the graph
  std::vector<LoopClosureInput> loops;
  bool dirty = false;
  double latest_stamp = 0.0;

  /// An unobserved building stays at its prior (unobserved_buildings_fixed).
  static bool heldAtPrior(const BuildingState& b, const GraphBackendParams& p) {
    return p.unobserved_buildings_fixed && b.observations == 0;
  }

  /// One more robot<->building edge on b: an observed building is free to move.
  void observed(BuildingState& b, const GraphBackendParams& p) {
    if (b.observations++ == 0 && b.vertex_id >= 0 && p.mode != OsmMode::kPrior)
      graph.setFixed(b.vertex_id, false);
  }

  int buildingVertex(BuildingState& b, const GraphBackendParams& p) {
    if (b.vertex_id >= 0) return b.vertex_id;
    b.vertex_id = next_building_vertex++;
    const bool fixed = p.mode == OsmMode::kPrior || heldAtPrior(b, p);
    graph.addVertexSE2(b.vertex_id, b.pose, fixed);
    Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
    info(0, 0) = info(1, 1) = 1.0 / (p.building_prior_std_xy * p.building_prior_std_xy);
    info(2, 2) = 1.0 / (p.building_prior_std_theta * p.building_prior_std_theta);
    if (p.osm_datum_std_xy > 0.0 && !fixed)
      graph.addEdgeSE2(datumVertex(p), b.vertex_id, b.prior.reference_pose, info,
                       EdgeOptions{1, {}});
    else
      graph.addPriorSE2(b.vertex_id, b.prior.reference_pose, info, EdgeOptions{1, {}});
    return b.vertex_id;
  }

  /// Where a building is expected before anything observed it: its prior moved by the datum.
  Pose2 predictedPose(const BuildingState& b, const GraphBackendParams& p) const {
    if (p.osm_datum_std_xy <= 0.0) return b.prior.reference_pose;
    return graph.vertexSE2(GraphBackend::kOsmDatumVertex).value_or(Pose2()) *
           b.prior.reference_pose;
  }

  /// The OSM datum: where the map as a whole sits relative to ENU, held at zero by a prior.
  int datumVertex(const GraphBackendParams& p) {
    const int id = GraphBackend::kOsmDatumVertex;
    if (graph.hasVertex(id)) return id;
    graph.addVertexSE2(id, Pose2());
    // Translation only unless a rotation deviation is given (1e-5 rad: 2 mm at 200 m).
    const double std_theta = p.osm_datum_std_theta > 0.0 ? p.osm_datum_std_theta : 1e-5;
    Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
    info(0, 0) = info(1, 1) = 1.0 / (p.osm_datum_std_xy * p.osm_datum_std_xy);
    info(2, 2) = 1.0 / (std_theta * std_theta);
    graph.addPriorSE2(id, Pose2(), info, EdgeOptions{1, {}});
    return id;
  }
};

GraphBackend::GraphBackend(const GraphBackendParams& params, std::shared_ptr<const Logger> logger)
    : params_(params),
      logger_(logger ? std::move(logger) : std::make_shared<Logger>()),
      matcher_(params.matcher),
      pending_(std::make_unique<Pending>()),
      state_(std::make_unique<State>()) {
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
  std::lock_guard<std::mutex> lock(queue_mutex_);
  pending_->keyframes.push_back(std::move(keyframe));
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
  if (params_.use_osm) processOsmPriors(report);
  if (state_->dirty || force_optimize) {
    optimizePhases(report);
    state_->dirty = false;
    // Keyframes matched while the datum was elsewhere are matched again where it is now.
    if (params_.use_osm && reassociateAfterDatumMoved(report) > 0) {
      processOsmPriors(report);
      optimizePhases(report);
    }
  }
  report.total_ms = msSince(t0);
  return report;
}

void GraphBackend::flushKeyframes(BackendUpdateReport& report) {
  std::deque<KeyframeInput> incoming;
  std::map<uint64_t, std::vector<LineSegment2>> segments;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    incoming.swap(pending_->keyframes);
    segments.swap(pending_->segments);
  }
  State& s = *state_;
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
  std::sort(incoming.begin(), incoming.end(),
            [](const KeyframeInput& a, const KeyframeInput& b) { return a.id < b.id; });
  for (auto& in : incoming) {
    if (in.id >= static_cast<uint64_t>(kOsmDatumVertex)) {
      logger_->warnOnce("kf_id", "keyframe id " + std::to_string(in.id) + " is too large; ignored");
      continue;
    }
    if (!s.keyframes.empty() && in.id <= s.keyframes.rbegin()->first) {
      logger_->warnOnce("kf_order", "keyframe " + std::to_string(in.id) +
                                        " is not newer than the last one (" +
                                        std::to_string(s.keyframes.rbegin()->first) +
                                        "); duplicate or out of order, ignored");
      continue;
    }
    KeyframeState kf;
    kf.id = in.id;
    kf.stamp = in.stamp;
    kf.odom_pose = in.odom_pose;
    kf.accum_distance = in.accum_distance;
    kf.odom_fitness = in.odom_fitness;
    kf.reanchored = in.reanchored;
    kf.gravity_roll_pitch = in.gravity_roll_pitch;
    if (in.floor) s.early_floors[in.id] = *in.floor;
    kf.cloud = in.cloud;
    const int vid = static_cast<int>(in.id);
    if (s.keyframes.empty()) {
      // The first keyframe sits at its GNSS position, else at the map origin (the first GPS fix),
      // with the known heading, or odometry's until the first global matching sets it.
      if (!in.gnss_position)
        logger_->info("first keyframe " + std::to_string(in.id) +
                      " has no GNSS position: fixed at the map origin (the first fix)");
      s.map_to_odom = initialMapToOdom(in.odom_pose, s.initial_yaw,
                                       in.gnss_position.value_or(Eigen::Vector2d::Zero()));
      kf.map_pose = s.map_to_odom * in.odom_pose;
      if (in.gravity_roll_pitch) {
        // Fixed with the IMU's roll and pitch, not odometry's (level at its start): otherwise
        // the fixed first vertex and the attitude priors of the others disagree by the slope.
        kf.map_pose = attitudeMeasurement(kf.map_pose, in.gravity_roll_pitch->x(),
                                          in.gravity_roll_pitch->y());
        s.map_to_odom = kf.map_pose * in.odom_pose.inverse();
      }
      const bool gnss_held = gnssPriors() && in.gnss_position.has_value();
      const bool soft_anchor =
          params_.initial_yaw_known && params_.anchor_std_xy > 0.0 && params_.anchor_std_yaw > 0.0;
      s.graph.addVertexSE3(vid, kf.map_pose, !gnss_held && !soft_anchor);
      if (gnss_held || soft_anchor) {
        // Held where GNSS cannot say: height, attitude; x and y by the fixes (GNSS priors) or
        // by the anchor's deviation, the heading by the INS's.
        const double anchor_std =
            in.gnss_std && *in.gnss_std > 0.0 ? *in.gnss_std : params_.anchor_std_xy;
        const double xy_info = gnss_held ? 1e-6 : 1.0 / std::pow(anchor_std, 2);
        const double yaw_std = gnss_held ? params_.gnss_first_yaw_std : params_.anchor_std_yaw;
        Matrix6d info = Matrix6d::Zero();
        info.diagonal() << xy_info, xy_info, 1.0 / (0.05 * 0.05), 1.0 / (0.01 * 0.01),
            1.0 / (0.01 * 0.01), 1.0 / std::pow(yaw_std, 2);
        s.graph.addPriorSE3(vid, kf.map_pose, info, EdgeOptions{0, {}});
      }
    } else {
      const KeyframeState& prev = s.keyframes.rbegin()->second;
      const Eigen::Isometry3d delta = prev.odom_pose.inverse() * in.odom_pose;
      kf.map_pose = prev.map_pose * delta;
      s.graph.addVertexSE3(vid, kf.map_pose);
      Matrix6d info = odometryInformation(in.odom_fitness, params_.odometry, delta.translation());
      if (in.reanchored) {
        info.setZero();
        info.diagonal().head<3>().setConstant(1.0 / std::pow(params_.reanchor_std_xyz, 2));
        info.diagonal().tail<3>().setConstant(1.0 / std::pow(params_.reanchor_std_rot, 2));
        logger_->info("keyframe " + std::to_string(in.id) +
                      " was re-anchored after a lost track: weak odometry edge");
      }
      s.graph.addEdgeSE3(static_cast<int>(prev.id), vid, delta, info, EdgeOptions{0, {}});
      // Levels >= 1 (the joint phase) see the odometry joint_odometry_weight times stiffer: the
      // buildings then correct the drift smoothly instead of kinking single keyframes.
      if (params_.joint_odometry_weight > 1.0)
        s.graph.addEdgeSE3(static_cast<int>(prev.id), vid, delta,
                           (params_.joint_odometry_weight - 1.0) * info, EdgeOptions{1, {}});
    }
    if (gnssPriors() && in.gnss_position) {
      const double info = 1.0 / std::pow(params_.gnss_prior_std, 2);
      s.graph.addPriorSE3XY(vid, *in.gnss_position, info * Eigen::Matrix2d::Identity(),
                            EdgeOptions{0, RobustKernel::huber(params_.gnss_prior_kernel_width)});
    }
    if (in.gravity_roll_pitch) {
      kf.has_attitude = true;
      s.graph.addPriorSE3(
          vid,
          attitudeMeasurement(kf.map_pose, in.gravity_roll_pitch->x(), in.gravity_roll_pitch->y()),
          attitudeInformation(params_.imu_attitude_std), EdgeOptions{0, {}});
    }
    auto early = s.early_segments.find(in.id);
    if (early != s.early_segments.end()) {
      kf.segments = std::move(early->second);
      s.early_segments.erase(early);
    }
    s.latest_stamp = std::max(s.latest_stamp, in.stamp);
    s.keyframes.emplace(in.id, std::move(kf));
    ++report.keyframes_added;
    s.dirty = true;
  }
  // Segments for keyframes that will never come (older than the newest keyframe) are dropped.
  if (!s.keyframes.empty()) {
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
}

void GraphBackend::flushLoops(BackendUpdateReport& report) {
  State& s = *state_;
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
    s.graph.addEdgeSE3(static_cast<int>(loop.to_id), static_cast<int>(loop.from_id),
                       loop.relative_pose, loop.information,
                       EdgeOptions{0, kernelNamed(params_.loop_kernel, params_.loop_kernel_width)});
    s.loops.push_back(loop);
    ++report.loops_added;
    s.dirty = true;
  }
  s.early_loops.swap(keep);
}

void GraphBackend::flushBuildings(BackendUpdateReport& report) {
  std::deque<Pending::BuildingBatch> batches;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    batches.swap(pending_->buildings);
  }
  // Without OSM (the baseline) buildings are neither matched nor saved: save_map would otherwise
  // write the uncorrected prior as if it were a result.
  if (!params_.use_osm) return;
  State& s = *state_;
  for (auto& batch : batches) {
    s.coverage.emplace_back(batch.center, batch.radius);
    for (auto& b : batch.buildings) {
      if (b.outline_enu.size() < 3 || s.buildings.count(b.id)) continue;
      BuildingState state;
      state.prior = b;
      state.pose = s.predictedPose(state, params_);
      state.local_outline = transformPolygon(b.outline_enu, b.reference_pose.inverse());
      s.buildings.emplace(state.prior.id, std::move(state));
      ++report.buildings_added;
    }
  }
}

Eigen::Matrix3d GraphBackend::localInformation(const LineMatchResult& match) const {
  return scaledInformation(match.information, params_.local_edge_std_xy,
                           params_.local_edge_std_theta, params_.matcher);
}

bool GraphBackend::gnssPriors() const {
  // With the heading still unknown the first keyframe must stay fixed: global matching rotates
  // the trajectory about it.
  return params_.gnss_prior_std > 0.0 && params_.initial_yaw_known;
}

bool GraphBackend::keyframeCovered(const Eigen::Vector2d& position) const {
  for (const auto& [center, radius] : state_->coverage)
    if ((position - center).norm() <= radius) return true;
  return false;
}

void GraphBackend::processOsmPriors(BackendUpdateReport& report) {
  State& s = *state_;
  for (auto& [id, kf] : s.keyframes) {
    if (kf.osm_processed) continue;
    if (static_cast<int>(kf.segments.size()) < params_.min_keyframe_segments) {
      // Segments may still be on their way; give up once the keyframe is old.
      if (s.latest_stamp - kf.stamp > params_.osm_max_wait) kf.osm_processed = true;
      continue;
    }
    Pose2 robot = planarPose(kf.map_pose);
    if (!keyframeCovered(robot.translation())) {
      if (s.latest_stamp - kf.stamp > params_.osm_max_wait) {
        logger_->warnOnce("osm_wait", "no OSM buildings arrived for keyframe " +
                                          std::to_string(id) + " within " +
                                          std::to_string(params_.osm_max_wait) +
                                          " s; it gets no map prior (logged once)");
        kf.osm_processed = true;
      }
      continue;
    }
    kf.osm_processed = true;
    std::vector<BuildingState*> nearby;
    std::vector<LineSegment2> map_segments;
    for (auto& [bid, b] : s.buildings) {
      if (distanceToPolygon(robot.translation(), b.prior.outline_enu) > params_.osm_query_radius)
        continue;
      nearby.push_back(&b);
      map_segments.insert(map_segments.end(), b.prior.segments.begin(), b.prior.segments.end());
    }
    if (nearby.empty()) continue;

    // Global matching (§3.4): keyframe segments against every nearby building. Needed for the
    // initial heading, for robot priors (prior and rigid modes, or use_global_priors) and for
    // rigid mode's single transform.
    const bool unbounded = !s.heading_initialized;
    const bool robot_priors = params_.mode != OsmMode::kNonRigid || params_.use_global_priors;
    LineMatchResult global;
    bool accepted = false;
    if (unbounded || robot_priors) {
      global = matcher_.matchGlobal(kf.segments, map_segments, robot, unbounded);
      accepted = global.success && global.fitness >= params_.global_min_fitness &&
                 global.matched_segments >= params_.global_min_matched;
    }
    if (unbounded) {
      if (!accepted) continue;  // heading still unknown: try the next keyframe
      // Rotate the whole trajectory about the origin so that this keyframe gets the heading.
      const double dyaw = wrapAngle(global.transform.theta - robot.theta);
      rotateTrajectory(dyaw);
      s.heading_initialized = true;
      report.heading_initialized_now = true;
      logger_->info("initial heading set by global matching: rotated the trajectory by " +
                    std::to_string(dyaw * 180.0 / M_PI) + " deg (fitness " +
                    std::to_string(global.fitness) + ")");
      s.dirty = true;
      continue;
    }
    Pose2 observed_from = robot;
    if (robot_priors && accepted) {
      addGlobalPrior(kf, global);
      observed_from = global.transform;
      ++report.global_priors;
      s.dirty = true;
    } else if (robot_priors) {
      ++report.global_rejected;
    }
    if (params_.mode == OsmMode::kPrior) continue;

    if (params_.mode == OsmMode::kRigid) {
      if (!accepted) continue;
      // One transform for the whole neighbourhood: building = robot · G⁻¹ · prior.
      for (BuildingState* b : nearby) {
        const Pose2 z = global.transform.inverse() * b->prior.reference_pose;
        const Eigen::Matrix3d info =
            rotateInformation(localInformation(global), b->prior.reference_pose.theta);
        s.graph.addEdgeSE3SE2(static_cast<int>(id), s.buildingVertex(*b, params_), z, info,
                              EdgeOptions{1, {}});
        s.observed(*b, params_);
        ++report.building_edges;
      }
      continue;
    }

    // Non-rigid: each building aligned on its own to the keyframe's walls (local matching),
    // where the map's common offset (the datum, once estimated) predicts it.
    kf.matched_with_datum = s.graph.vertexSE2(kOsmDatumVertex);
    std::vector<LineSegment2> kf_map;
    kf_map.reserve(kf.segments.size());
    for (const auto& seg : kf.segments) kf_map.push_back(seg.transformed(observed_from));
    std::vector<Polygon2> outlines;  // current estimates: what hides the walls behind them
    for (const BuildingState* b : nearby)
      outlines.push_back(transformPolygon(b->local_outline, b->pose));
    std::vector<const Polygon2*> occluders;
    for (const Polygon2& o : outlines) occluders.push_back(&o);
    for (size_t i = 0; i < nearby.size(); ++i) {
      BuildingState* b = nearby[i];
      std::vector<LineSegment2> walls = polygonSegments(b->local_outline);
      if (params_.local_visible_walls_only) {
        std::vector<LineSegment2> seen;
        for (size_t w : visibleWalls(outlines[i], observed_from.translation(),
                                     params_.osm_query_radius, occluders))
          seen.push_back(walls[w]);
        if (static_cast<int>(seen.size()) < params_.local_min_visible_walls) {
          ++report.local_unseen;
          continue;
        }
        walls.swap(seen);
      }
      // Consecutive keyframes see a wall with the same errors (motion distortion, calibration):
      // one edge per building_edge_spacing metres of path, not one per keyframe.
      if (b->last_edge_distance &&
          kf.accum_distance - *b->last_edge_distance < params_.building_edge_spacing)
        continue;
      ++report.local_attempts;
      const LineMatchResult local = matcher_.matchLocal(walls, kf_map, b->pose);
      if (!local.success || local.fitness < params_.local_min_fitness ||
          local.matched_segments < params_.local_min_matched) {
        ++report.local_rejected;
        continue;
      }
      const Pose2 z = observed_from.inverse() * local.transform;
      Eigen::Matrix3d info = localInformation(local);
      if (params_.local_edge_at_walls)
        info = leverInformation(info, local.matched_centre - local.transform.translation());
      info = rotateInformation(info, local.transform.theta);
      // Joint optimisation moves this robot through planar edges: keep its roll and pitch.
      if (params_.joint_optimization && !kf.has_attitude) addOdometryAttitudePrior(kf, 1);
      const int edge = s.graph.addEdgeSE3SE2(
          static_cast<int>(id), s.buildingVertex(*b, params_), z, info,
          EdgeOptions{
              1, kernelNamed(params_.building_edge_kernel, params_.building_edge_kernel_width)});
      s.building_edges.push_back({edge, id, b->prior.id, z, info});
      b->last_edge_distance = kf.accum_distance;
      s.observed(*b, params_);
      ++report.building_edges;
      s.dirty = true;
    }
  }
}

void GraphBackend::flushFloors(BackendUpdateReport& report) {
  std::map<uint64_t, Eigen::Vector4d> floors;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    floors.swap(pending_->floors);
  }
  State& s = *state_;
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
  State& s = *state_;
  const std::optional<uint64_t> prev_id = s.last_floor_keyframe;
  if (prev_id && *prev_id >= kf.id) return;  // out of order: keep the newer chain
  s.last_floor_keyframe = kf.id;
  if (!params_.floor_edges || !prev_id) return;
  const KeyframeState& prev = s.keyframes.at(*prev_id);
  if (kf.accum_distance - prev.accum_distance > params_.floor_max_link_distance) {
    ++report.floor_gaps;
    return;
  }
  // The same ground only if the floors agree in the map frame (odometry links the two poses).
  const Eigen::Vector3d n_prev = prev.map_pose.linear() * prev.floor->head<3>();
  const Eigen::Vector3d n_this = kf.map_pose.linear() * kf.floor->head<3>();
  const double bend =
      std::acos(std::clamp(n_prev.normalized().dot(n_this.normalized()), -1.0, 1.0));
  if (bend > params_.floor_slope_change_deg * M_PI / 180.0) {
    ++report.floor_slope_changes;
    logger_->info("keyframe " + std::to_string(kf.id) + ": the floor bends by " +
                  std::to_string(bend * 180.0 / M_PI) + " deg (a change of slope): not tied to " +
                  "keyframe " + std::to_string(prev.id));
    return;
  }
  // Both floors are measured: the difference carries twice the variance of one.
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  info(0, 0) = info(1, 1) = 0.5 / std::pow(params_.floor_normal_std, 2);
  // With gravity from the IMU on both, the floor only says the height: a floor fit tilts with
  // the road's camber and curvature, gravity does not (sim: tilt error 0.038 -> 0.056 deg).
  if (prev.gravity_roll_pitch && kf.gravity_roll_pitch && !params_.floor_attitude_with_imu)
    info(0, 0) = info(1, 1) = 1e-9;
  info(2, 2) = 0.5 / std::pow(params_.floor_distance_std, 2);
  if (s.graph.addEdgeSE3PlanePair(
          static_cast<int>(prev.id), static_cast<int>(kf.id), *prev.floor, *kf.floor, info,
          EdgeOptions{0, RobustKernel::huber(params_.floor_kernel_width)}) < 0) {
    logger_->warnOnce("floor_edge", "floor edge rejected: " + s.graph.lastError());
    return;
  }
  s.keyframes.at(*prev_id).floor_tied = kf.floor_tied = true;
  ++report.floor_edges;
  s.dirty = true;
}

void GraphBackend::addGlobalPrior(KeyframeState& kf, const LineMatchResult& global) {
  State& s = *state_;
  const int vid = static_cast<int>(kf.id);
  const Eigen::Matrix3d info = scaledInformation(global.information, params_.global_prior_std_xy,
                                                 params_.global_prior_std_yaw, params_.matcher);
  s.graph.addPriorSE3XY(vid, global.transform.translation(), info.topLeftCorner<2, 2>(),
                        EdgeOptions{0, {}});
  s.graph.addPriorSE3Yaw(vid, global.transform.theta, info(2, 2), EdgeOptions{0, {}});
  kf.has_global_prior = true;
  if (!kf.has_attitude) addOdometryAttitudePrior(kf, 0);
}

void GraphBackend::addOdometryAttitudePrior(KeyframeState& kf, int level) {
  // A keyframe on a tied floor is kept level by the floor edges already; odometry's roll/pitch
  // (which drifts, e.g. with KITTI's elevation bias) would pull against them (real drive: the
  // OSM run sank 0.27 m while the run without OSM stayed on its floor).
  if (kf.floor_tied) {
    kf.has_attitude = true;
    return;
  }
  const Eigen::Vector2d rp = rollPitch(kf.map_pose);
  state_->graph.addPriorSE3(
      static_cast<int>(kf.id), attitudeMeasurement(kf.map_pose, rp.x(), rp.y()),
      attitudeInformation(params_.odometry_attitude_std), EdgeOptions{level, {}});
  kf.has_attitude = true;
}

void GraphBackend::optimizePhases(BackendUpdateReport& report) {
  State& s = *state_;
  const OptimizerOptions& options = params_.optimizer;

  // Phase 1 (level 0): robot poses from odometry, loops and global priors; buildings untouched.
  report.phase1 = s.graph.optimize(0, options);
  report.optimized = true;
  readRobotPoses();

  bool have_buildings = false;
  for (const auto& [bid, b] : s.buildings) have_buildings |= b.vertex_id >= 0;
  if (!have_buildings || params_.mode == OsmMode::kPrior) {
    updateMapToOdom();
    return;
  }
  // Phase 2 (level 1): robot vertices fixed, buildings move to satisfy their constraints.
  for (int edge : s.overlap_edges) s.graph.removeEdge(edge);  // re-derived below
  s.overlap_edges.clear();
  if (params_.use_shared_walls && params_.mode == OsmMode::kNonRigid) addSharedWallEdges(report);
  const std::vector<int> unfix = fixRobots();
  report.phase2 = s.graph.optimize(1, options);
  readBuildingPoses();
  if (params_.building_edge_gate_chi2 > 0.0 && gateBuildingEdges(report) > 0) {
    report.phase2 = s.graph.optimize(1, options);
    readBuildingPoses();
  }
  if (params_.joint_optimization) {
    // Phase 3 (level 1): everything together, from phase 2's buildings.
    for (int vid : unfix) s.graph.setFixed(vid, false);
    report.joint = s.graph.optimize(1, options);
    readRobotPoses();
    readBuildingPoses();
    fixRobots();
  }
  if (params_.resolve_overlaps) resolveOverlaps(report);
  for (int vid : unfix) s.graph.setFixed(vid, false);
  updateMapToOdom();
}

size_t GraphBackend::gateBuildingEdges(BackendUpdateReport& report) {
  // Robot<->building edges that disagree with the building as all its other observations place
  // it (after phase 2) are wrong associations: removed before they bend the trajectory.
  State& s = *state_;
  size_t removed = 0;
  std::vector<State::BuildingEdge> keep;
  keep.reserve(s.building_edges.size());
  for (const auto& e : s.building_edges) {
    auto kf = s.keyframes.find(e.keyframe);
    auto b = s.buildings.find(e.building);
    if (kf == s.keyframes.end() || b == s.buildings.end()) continue;
    const Pose2 predicted = planarPose(kf->second.map_pose) * e.z;
    // The SE3-SE2 edge's error (up to sign): translation in the estimated building's axes.
    const Pose2 d = b->second.pose.inverse() * predicted;
    const Eigen::Vector3d err(d.x, d.y, wrapAngle(d.theta));
    if (err.dot(e.information * err) <= params_.building_edge_gate_chi2) {
      keep.push_back(e);
      continue;
    }
    s.graph.removeEdge(e.edge_id);
    if (b->second.observations > 0) --b->second.observations;
    if (State::heldAtPrior(b->second, params_) && b->second.vertex_id >= 0) {
      // Nothing observes it any more: back to its prior, held there.
      b->second.pose = b->second.prior.reference_pose;
      s.graph.setVertexSE2(b->second.vertex_id, b->second.pose);
      s.graph.setFixed(b->second.vertex_id, true);
    }
    ++removed;
  }
  s.building_edges.swap(keep);
  report.building_edges_gated += removed;
  return removed;
}

size_t GraphBackend::reassociateAfterDatumMoved(BackendUpdateReport& report) {
  State& s = *state_;
  const std::optional<Pose2> datum = s.graph.vertexSE2(kOsmDatumVertex);
  if (!datum || params_.osm_datum_reassociate_distance <= 0.0) return 0;
  std::set<uint64_t> stale;
  for (auto& [id, kf] : s.keyframes) {
    if (!kf.matched_with_datum) continue;
    const double moved = (kf.matched_with_datum->translation() - datum->translation()).norm();
    if (moved > params_.osm_datum_reassociate_distance) stale.insert(id);
  }
  if (stale.empty()) return 0;
  std::vector<State::BuildingEdge> keep;
  std::set<int64_t> touched;
  for (const auto& e : s.building_edges) {
    if (!stale.count(e.keyframe)) {
      keep.push_back(e);
      continue;
    }
    s.graph.removeEdge(e.edge_id);
    BuildingState& b = s.buildings.at(e.building);
    if (b.observations > 0) --b.observations;
    b.last_edge_distance.reset();
    touched.insert(e.building);
  }
  s.building_edges.swap(keep);
  // A building only those keyframes observed goes back to where the datum predicts it.
  for (int64_t id : touched) {
    BuildingState& b = s.buildings.at(id);
    if (b.observations > 0 || b.vertex_id < 0) continue;
    b.pose = s.predictedPose(b, params_);
    s.graph.setVertexSE2(b.vertex_id, b.pose);
  }
  for (uint64_t id : stale) {
    s.keyframes.at(id).osm_processed = false;
    s.keyframes.at(id).matched_with_datum.reset();
  }
  report.osm_reassociated += stale.size();
  logger_->info("OSM datum moved: " + std::to_string(stale.size()) +
                " keyframes matched again at the map's new offset");
  return stale.size();
}

std::vector<int> GraphBackend::fixRobots() {
  State& s = *state_;
  std::vector<int> fixed_now;
  for (const auto& [id, kf] : s.keyframes) {
    const int vid = static_cast<int>(id);
    if (!s.graph.isFixed(vid)) {
      s.graph.setFixed(vid, true);
      fixed_now.push_back(vid);
    }
  }
  return fixed_now;
}

void GraphBackend::readRobotPoses() {
  for (auto& [id, kf] : state_->keyframes)
    if (auto pose = state_->graph.vertexSE3(static_cast<int>(id))) kf.map_pose = *pose;
}

void GraphBackend::readBuildingPoses() {
  State& s = *state_;
  for (auto& [bid, b] : s.buildings) {
    if (auto pose = s.graph.vertexSE2(b.vertex_id))
      b.pose = *pose;
    else
      b.pose = s.predictedPose(b, params_);
  }
}

void GraphBackend::findNewContacts() {
  State& s = *state_;
  if (s.shared_walls_searched == s.buildings.size()) return;
  s.shared_walls_searched = s.buildings.size();
  std::vector<int64_t> ids;
  std::vector<Polygon2> outlines;
  for (const auto& [bid, b] : s.buildings) {
    ids.push_back(bid);
    outlines.push_back(b.prior.outline_enu);
  }
  for (const auto& c : findBuildingContacts(outlines, params_.shared_walls))
    s.shared_walls.try_emplace(std::make_pair(ids[c.a], ids[c.b]), State::SharedWall{c, false});
}

void GraphBackend::addSharedWallEdges(BackendUpdateReport& report) {
  // Pairs join the graph once one of the two buildings is in it; the other follows (and so on
  // along a row), so a building nobody saw moves with the neighbour it shares a wall with.
  State& s = *state_;
  findNewContacts();
  const double info = 1.0 / (params_.shared_wall_std * params_.shared_wall_std);
  const EdgeOptions options{1, RobustKernel::huber(params_.shared_wall_kernel_width)};
  for (bool changed = true; changed;) {
    changed = false;
    for (auto& [key, wall] : s.shared_walls) {
      if (wall.tied) continue;
      BuildingState& a = s.buildings.at(key.first);
      BuildingState& b = s.buildings.at(key.second);
      if (a.vertex_id < 0 && b.vertex_id < 0) continue;
      if (params_.unobserved_buildings_fixed && (a.observations == 0 || b.observations == 0))
        continue;  // tied once both are observed
      const BuildingContact& c = wall.contact;
      const Pose2& pa = a.prior.reference_pose;
      const Pose2& pb = b.prior.reference_pose;
      const Eigen::Vector2d normal = pb.rotation().transpose() * c.b_normal;
      const double offset = normal.dot(pb.inverse().transform(c.b_point));
      const int va = s.buildingVertex(a, params_), vb = s.buildingVertex(b, params_);
      for (const auto& end : c.a_ends)
        s.graph.addEdgeSE2PointOnLine(va, vb, pa.inverse().transform(end), normal, offset, info,
                                      options);
      wall.tied = true;
      changed = true;
    }
  }
  for (const auto& [key, wall] : s.shared_walls) report.shared_walls += wall.tied ? 1 : 0;
}

void GraphBackend::resolveOverlaps(BackendUpdateReport& report) {
  // Algorithm 3.2: hard building↔building edges from the overlap-removal matcher, re-optimised
  // at level 2 (robots stay fixed), until no outline intersects or the iterations run out.
  State& s = *state_;
  const OptimizerOptions& options = params_.optimizer;
  // Separating two buildings says nothing about where the map as a whole sits.
  const bool datum = s.graph.hasVertex(kOsmDatumVertex);
  if (datum) s.graph.setFixed(kOsmDatumVertex, true);
  std::vector<BuildingState*> order;
  std::vector<Building> outlines;
  for (auto& [bid, b] : s.buildings) {
    order.push_back(&b);
    outlines.push_back(b.corrected());
  }
  auto overlaps = findOverlappingBuildings(outlines, params_.overlap_min_area);
  for (int iter = 0; iter < params_.overlap_max_iterations && !overlaps.empty(); ++iter) {
    size_t added = 0;
    for (const auto& [i, j] : overlaps) {
      // Move the less observed building (a building nobody saw has only its OSM prior).
      BuildingState* a = order[i];
      BuildingState* b = order[j];
      if (a->observations > b->observations) std::swap(a, b);
      const LineMatchResult sep = matcher_.removeOverlap(
          a->local_outline, a->pose, transformPolygon(b->local_outline, b->pose));
      if (!sep.success) continue;
      const Pose2 target = withClearance(sep.transform, a->pose, params_.overlap_clearance);
      const Pose2 z = target.inverse() * b->pose;  // relPose of Alg. 3.2, line 10
      const Eigen::Matrix3d info = Eigen::Matrix3d::Identity() * params_.overlap_information;
      const int edge =
          s.graph.addEdgeSE2(s.buildingVertex(*a, params_), s.buildingVertex(*b, params_), z, info,
                             EdgeOptions{2, {}});
      if (edge >= 0) {
        s.overlap_edges.push_back(edge);
        ++added;
      }
      // Two buildings nobody saw whose priors overlap: the prior itself is wrong, one must move.
      if (b->observations == 0 && params_.mode != OsmMode::kPrior)
        s.graph.setFixed(a->vertex_id, false);
    }
    report.overlap_iterations = static_cast<size_t>(iter + 1);
    report.overlap_edges += added;
    if (added == 0) break;
    report.overlap = s.graph.optimize(2, options);
    outlines.clear();
    for (BuildingState* b : order) {
      if (auto pose = s.graph.vertexSE2(b->vertex_id)) b->pose = *pose;
      outlines.push_back(b->corrected());
    }
    overlaps = findOverlappingBuildings(outlines, params_.overlap_min_area);
  }
  if (datum) s.graph.setFixed(kOsmDatumVertex, false);
  report.overlaps_remaining = overlaps.size();
}

void GraphBackend::rotateTrajectory(double dyaw) {
  State& s = *state_;
  // About the first keyframe, which is fixed where GNSS put it.
  const Eigen::Vector2d pivot =
      s.keyframes.empty()
          ? Eigen::Vector2d::Zero()
          : Eigen::Vector2d(s.keyframes.begin()->second.map_pose.translation().head<2>());
  const Eigen::Vector2d shift = pivot - Pose2(0.0, 0.0, dyaw).rotation() * pivot;
  const Eigen::Isometry3d rot = isometryFromPlanar(Pose2(shift.x(), shift.y(), dyaw));
  for (auto& [id, kf] : s.keyframes) {
    kf.map_pose = rot * kf.map_pose;
    s.graph.setVertexSE3(static_cast<int>(id), kf.map_pose);
  }
  s.map_to_odom = rot * s.map_to_odom;
}

void GraphBackend::setInitialHeading(double yaw) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  State& s = *state_;
  if (s.heading_initialized) return;
  s.heading_initialized = true;
  s.initial_yaw = yaw;
  if (s.keyframes.empty()) return;  // applied when the first keyframe arrives
  rotateTrajectory(wrapAngle(yaw - planarPose(s.keyframes.begin()->second.map_pose).theta));
  s.dirty = true;
  logger_->info("initial heading set to " + std::to_string(yaw * 180.0 / M_PI) + " deg");
}

void GraphBackend::updateMapToOdom() {
  State& s = *state_;
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

std::vector<BuildingState> GraphBackend::buildings() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<BuildingState> out;
  for (const auto& [id, b] : state_->buildings) out.push_back(b);
  return out;
}

std::vector<Building> GraphBackend::correctedBuildings() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<Building> out;
  for (const auto& [id, b] : state_->buildings) {
    Building c = b.corrected();
    c.tags[kObservationsTag] = std::to_string(b.observations);
    if (state_->origin) {
      c.outline_geo.clear();
      for (const auto& v : c.outline_enu) c.outline_geo.push_back(state_->origin->toGeoPoint(v));
    }
    out.push_back(std::move(c));
  }
  return out;
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

}  // namespace osm_graph_slam
