#include "osm_association.h"

#include <cmath>
#include <set>

#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/information.h"
#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {

void OsmAssociation::process(BackendState& s, BackendUpdateReport& report) const {
  for (auto& [id, kf] : s.keyframes) {
    if (kf.osm_processed || !ready(s, id, kf)) continue;
    kf.osm_processed = true;
    const Pose2 robot = planarPose(kf.map_pose);
    const Neighbourhood near = nearby(s, robot);
    if (near.buildings.empty()) continue;

    // Global matching (§3.4): keyframe segments against every nearby building. Needed for the
    // initial heading, for robot priors (prior and rigid modes, or use_global_priors) and for
    // rigid mode's single transform.
    const bool unbounded = !s.heading_initialized;
    const bool robot_priors = mode_ != OsmMode::kNonRigid || params_.use_global_priors;
    LineMatchResult global;
    bool accepted = false;
    if (unbounded || robot_priors) {
      global = matcher_.matchGlobal(kf.segments, near.segments, robot, unbounded);
      accepted = global.success && global.fitness >= params_.global_min_fitness &&
                 global.matched_segments >= params_.global_min_matched;
    }
    if (unbounded) {
      if (accepted) initializeHeading(s, id, robot, global, report);
      continue;  // heading still unknown: try the next keyframe
    }
    Pose2 observed_from = robot;
    if (robot_priors && accepted) {
      addGlobalPrior(s, kf, global);
      observed_from = global.transform;
      ++report.global_priors;
      s.dirty = true;
    } else if (robot_priors) {
      ++report.global_rejected;
    }
    if (mode_ == OsmMode::kRigid && accepted)
      addRigidEdges(s, id, near, global, report);
    else if (mode_ == OsmMode::kNonRigid)
      addNonRigidEdges(s, id, kf, near, observed_from, report);
  }
}

bool OsmAssociation::ready(const BackendState& s, uint64_t id, KeyframeState& kf) const {
  // Where an unplaced session is in the map is a guess; its keyframes wait until it is placed.
  if (s.unplaced_sessions.count(kf.session)) return false;
  const bool old = s.latest_stamp - kf.stamp > params_.osm_max_wait;
  if (static_cast<int>(kf.segments.size()) < params_.min_keyframe_segments) {
    // Segments may still be on their way; give up once the keyframe is old.
    if (old) kf.osm_processed = true;
    return false;
  }
  if (s.covered(planarPose(kf.map_pose).translation())) return true;
  if (old) {
    logger_.warnOnce("osm_wait", "no OSM buildings arrived for keyframe " + std::to_string(id) +
                                     " within " + std::to_string(params_.osm_max_wait) +
                                     " s; it gets no map prior (logged once)");
    kf.osm_processed = true;
  }
  return false;
}

OsmAssociation::Neighbourhood OsmAssociation::nearby(BackendState& s, const Pose2& robot) const {
  Neighbourhood near;
  for (auto& [bid, b] : s.buildings) {
    if (distanceToPolygon(robot.translation(), b.prior.outline_enu) > params_.osm_query_radius)
      continue;
    near.buildings.push_back(&b);
    near.segments.insert(near.segments.end(), b.prior.segments.begin(), b.prior.segments.end());
  }
  return near;
}

void OsmAssociation::initializeHeading(BackendState& s, uint64_t id, const Pose2& robot,
                                       const LineMatchResult& global,
                                       BackendUpdateReport& report) const {
  // Rotate the whole trajectory about the origin so that this keyframe gets the heading.
  const double dyaw = wrapAngle(global.transform.theta - robot.theta);
  s.rotateTrajectory(dyaw);
  s.heading_initialized = true;
  report.heading_initialized_now = true;
  report.heading_from_map =
      BackendUpdateReport::HeadingFromMap{id, global.transform, dyaw, global.fitness};
  logger_.info("initial heading set by global matching: rotated the trajectory by " +
               std::to_string(dyaw * 180.0 / M_PI) + " deg (fitness " +
               std::to_string(global.fitness) + ")");
  s.dirty = true;
}

void OsmAssociation::addRigidEdges(BackendState& s, uint64_t id, const Neighbourhood& near,
                                   const LineMatchResult& global,
                                   BackendUpdateReport& report) const {
  // One transform for the whole neighbourhood: building = robot · G⁻¹ · prior.
  for (BuildingState* b : near.buildings) {
    const Pose2 z = global.transform.inverse() * b->prior.reference_pose;
    const Eigen::Matrix3d info =
        rotateInformation(localInformation(global), b->prior.reference_pose.theta);
    s.graph.addEdgeSE3SE2(static_cast<int>(id), s.buildingVertex(*b, mode_, prior_), z, info,
                          EdgeOptions{1, {}});
    s.observed(*b, mode_);
    ++report.building_edges;
  }
}

void OsmAssociation::addNonRigidEdges(BackendState& s, uint64_t id, KeyframeState& kf,
                                      const Neighbourhood& near, const Pose2& observed_from,
                                      BackendUpdateReport& report) const {
  // Each building aligned on its own to the keyframe's walls (local matching), where the map's
  // common offset (the datum, once estimated) predicts it.
  kf.matched_with_datum = s.graph.vertexSE2(GraphBackend::kOsmDatumVertex);
  std::vector<LineSegment2> kf_map;
  kf_map.reserve(kf.segments.size());
  for (const auto& seg : kf.segments) kf_map.push_back(seg.transformed(observed_from));
  std::vector<Polygon2> outlines;  // current estimates: what hides the walls behind them
  for (const BuildingState* b : near.buildings)
    outlines.push_back(transformPolygon(b->local_outline, b->pose));
  std::vector<const Polygon2*> occluders;
  for (const Polygon2& o : outlines) occluders.push_back(&o);
  for (size_t i = 0; i < near.buildings.size(); ++i) {
    BuildingState* b = near.buildings[i];
    const std::vector<LineSegment2> walls =
        visibleWallsOf(*b, outlines[i], occluders, observed_from);
    if (walls.empty()) {
      ++report.local_unseen;
      continue;
    }
    // Consecutive keyframes see a wall with the same errors (motion distortion, calibration):
    // one edge per building_edge_spacing metres of path, not one per keyframe.
    if (b->last_edge_distance && b->last_edge_session == kf.session &&
        kf.accum_distance - *b->last_edge_distance < params_.building_edge_spacing)
      continue;
    ++report.local_attempts;
    const LineMatchResult local = matcher_.matchLocal(walls, kf_map, b->pose);
    if (!local.success || local.fitness < params_.local_min_fitness ||
        local.matched_segments < params_.local_min_matched) {
      ++report.local_rejected;
      continue;
    }
    addLocalEdge(s, id, kf, *b, observed_from, local, report);
  }
}

std::vector<LineSegment2> OsmAssociation::visibleWallsOf(
    const BuildingState& b, const Polygon2& outline, const std::vector<const Polygon2*>& occluders,
    const Pose2& observed_from) const {
  std::vector<LineSegment2> walls = polygonSegments(b.local_outline);
  if (!params_.local_visible_walls_only) return walls;
  std::vector<LineSegment2> seen;
  for (size_t w :
       visibleWalls(outline, observed_from.translation(), params_.osm_query_radius, occluders))
    seen.push_back(walls[w]);
  if (static_cast<int>(seen.size()) < params_.local_min_visible_walls) seen.clear();
  return seen;
}

void OsmAssociation::addLocalEdge(BackendState& s, uint64_t id, KeyframeState& kf, BuildingState& b,
                                  const Pose2& observed_from, const LineMatchResult& local,
                                  BackendUpdateReport& report) const {
  const Pose2 z = observed_from.inverse() * local.transform;
  Eigen::Matrix3d info = localInformation(local);
  if (params_.local_edge_at_walls)
    info = leverInformation(info, local.matched_centre - local.transform.translation());
  info = rotateInformation(info, local.transform.theta);
  // Joint optimisation moves this robot through planar edges: keep its roll and pitch.
  if (joint_optimization_ && !kf.has_attitude) addOdometryAttitudePrior(s, kf, 1);
  const int edge = s.graph.addEdgeSE3SE2(
      static_cast<int>(id), s.buildingVertex(b, mode_, prior_), z, info,
      EdgeOptions{1,
                  kernelNamed(params_.building_edge_kernel, params_.building_edge_kernel_width)});
  s.building_edges.push_back({edge, id, b.prior.id, z, info});
  b.last_edge_distance = kf.accum_distance;
  b.last_edge_session = kf.session;
  s.observed(b, mode_);
  ++report.building_edges;
  s.dirty = true;
}

void OsmAssociation::addGlobalPrior(BackendState& s, KeyframeState& kf,
                                    const LineMatchResult& global) const {
  const int vid = static_cast<int>(kf.id);
  const Eigen::Matrix3d info = scaledInformation(global.information, params_.global_prior_std_xy,
                                                 params_.global_prior_std_yaw, matcher_.params());
  s.graph.addPriorSE3XY(vid, global.transform.translation(), info.topLeftCorner<2, 2>(),
                        EdgeOptions{0, {}});
  s.graph.addPriorSE3Yaw(vid, global.transform.theta, info(2, 2), EdgeOptions{0, {}});
  kf.has_global_prior = true;
  if (!kf.has_attitude) addOdometryAttitudePrior(s, kf, 0);
}

void OsmAssociation::addOdometryAttitudePrior(BackendState& s, KeyframeState& kf, int level) const {
  // A keyframe on a tied floor is kept level by the floor edges already; odometry's roll/pitch
  // (which drifts, e.g. with KITTI's elevation bias) would pull against them (real drive: the
  // OSM run sank 0.27 m while the run without OSM stayed on its floor).
  if (kf.floor_tied) {
    kf.has_attitude = true;
    return;
  }
  const Eigen::Vector2d rp = rollPitchOf(Eigen::Matrix3d(kf.map_pose.rotation()));
  s.graph.addPriorSE3(static_cast<int>(kf.id), attitudeMeasurement(kf.map_pose, rp.x(), rp.y()),
                      attitudeInformation(odometry_attitude_std_), EdgeOptions{level, {}});
  kf.has_attitude = true;
}

Eigen::Matrix3d OsmAssociation::localInformation(const LineMatchResult& match) const {
  return scaledInformation(match.information, params_.local_edge_std_xy,
                           params_.local_edge_std_theta, matcher_.params());
}

size_t OsmAssociation::reassociateAfterDatumMoved(BackendState& s,
                                                  BackendUpdateReport& report) const {
  const std::optional<Pose2> datum = s.graph.vertexSE2(GraphBackend::kOsmDatumVertex);
  const double distance = s.mapWeighting(prior_).datum_reassociate_distance;
  if (!datum || distance <= 0.0) return 0;
  std::set<uint64_t> stale;
  for (auto& [id, kf] : s.keyframes) {
    if (!kf.matched_with_datum) continue;
    const double moved = (kf.matched_with_datum->translation() - datum->translation()).norm();
    if (moved > distance) stale.insert(id);
  }
  if (stale.empty()) return 0;
  std::vector<BuildingEdgeRecord> keep;
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
    b.pose = s.predictedPose(b, prior_);
    s.graph.setVertexSE2(b.vertex_id, b.pose);
  }
  for (uint64_t id : stale) {
    s.keyframes.at(id).osm_processed = false;
    s.keyframes.at(id).matched_with_datum.reset();
  }
  report.osm_reassociated += stale.size();
  logger_.info("OSM datum moved: " + std::to_string(stale.size()) +
               " keyframes matched again at the map's new offset");
  return stale.size();
}

}  // namespace osm_graph_slam
