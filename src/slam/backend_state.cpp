#include "backend_state.h"

#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/planar_pose.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace osm_graph_slam {

void BackendState::observed(BuildingState& b, OsmMode mode) {
  if (b.observations++ == 0 && b.vertex_id >= 0 && mode != OsmMode::kPrior)
    graph.setFixed(b.vertex_id, false);
}

int BackendState::buildingVertex(BuildingState& b, OsmMode mode, const OsmPriorParams& p) {
  if (b.vertex_id >= 0) return b.vertex_id;
  b.vertex_id = next_building_vertex++;
  const bool fixed = mode == OsmMode::kPrior || heldAtPrior(b, p);
  graph.addVertexSE2(b.vertex_id, b.pose, fixed);
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  const double std_xy = mapWeighting(p).building_std_xy;
  info(0, 0) = info(1, 1) = 1.0 / (std_xy * std_xy);
  info(2, 2) = 1.0 / (p.building_prior_std_theta * p.building_prior_std_theta);
  if (datumStdXy(p) > 0.0 && !fixed)
    graph.addEdgeSE2(datumVertex(p), b.vertex_id, b.prior.reference_pose, info, EdgeOptions{1, {}});
  else
    graph.addPriorSE2(b.vertex_id, b.prior.reference_pose, info, EdgeOptions{1, {}});
  return b.vertex_id;
}

Pose2 BackendState::predictedPose(const BuildingState& b, const OsmPriorParams& p) const {
  if (datumStdXy(p) <= 0.0) return b.prior.reference_pose;
  return graph.vertexSE2(GraphBackend::kOsmDatumVertex).value_or(Pose2()) * b.prior.reference_pose;
}

int BackendState::datumVertex(const OsmPriorParams& p) {
  const int id = GraphBackend::kOsmDatumVertex;
  if (graph.hasVertex(id)) return id;
  graph.addVertexSE2(id, Pose2());
  // Translation only unless a rotation deviation is given (1e-5 rad: 2 mm at 200 m).
  const double std_theta = p.osm_datum_std_theta > 0.0 ? p.osm_datum_std_theta : 1e-5;
  const MapWeighting w = mapWeighting(p);
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  info(0, 0) = info(1, 1) = 1.0 / (w.datum_std_xy * w.datum_std_xy);
  info(2, 2) = 1.0 / (std_theta * std_theta);
  graph.addPriorSE2(id, Pose2(), info,
                    EdgeOptions{1, kernelNamed(w.datum_kernel, p.osm_datum_kernel_width)});
  return id;
}

BackendState::MapWeighting BackendState::mapWeighting(const OsmPriorParams& p) const {
  if (gnssAnchored())
    return {p.building_prior_std_xy, p.osm_datum_std_xy, p.osm_datum_kernel,
            p.osm_datum_reassociate_distance};
  return {p.building_prior_std_xy_without_gnss, p.osm_datum_std_xy_without_gnss,
          p.osm_datum_kernel_without_gnss, p.osm_datum_reassociate_distance_without_gnss};
}

uint32_t BackendState::sessionOf(uint64_t keyframe) const {
  const auto it = keyframes.find(keyframe);
  return it != keyframes.end() ? it->second.session : 0;
}

namespace {
constexpr double kLastWindow = GraphBackend::kSessionWindows - 1;
}  // namespace

int BackendState::gnssBiasWindow(const Session& session, double stamp, const GnssParams& p) {
  const double windows =
      session.gnss_bias_start && std::isfinite(stamp)
          ? (stamp - *session.gnss_bias_start) / std::max(p.gnss_bias_window, 1e-3)
          : 0.0;
  return static_cast<int>(std::clamp(std::floor(windows), 0.0, kLastWindow));
}

int BackendState::odometryScaleWindow(double accum_distance, const OdometryEdgeParams& p) {
  // A non-finite path length (a corrupt message) counts as the first window.
  const double windows =
      std::isfinite(accum_distance) ? accum_distance / p.odometry_scale_window : 0.0;
  return static_cast<int>(std::clamp(std::floor(windows), 0.0, kLastWindow));
}

int BackendState::gnssBiasVertex(uint32_t session_id, double stamp, const GnssParams& p,
                                 double scale) {
  Session& session = sessions[session_id];
  if (!session.gnss_bias_start) session.gnss_bias_start = stamp;
  const int k = gnssBiasWindow(session, stamp, p);
  auto& vertices = session.gnss_bias_vertices;
  const auto found = vertices.find(k);
  if (found != vertices.end()) return found->second;
  const int id = GraphBackend::kGnssBiasVertexTop -
                 static_cast<int>(session_id) * GraphBackend::kSessionWindows - k;
  // Without altitude evidence the vertical bias is unused; any positive deviation keeps it tame.
  const double vertical = p.gnss_bias_std_vertical > 0.0 ? p.gnss_bias_std_vertical : 1.0;
  const Eigen::Vector3d var =
      Eigen::Vector3d(p.gnss_bias_std * p.gnss_bias_std, p.gnss_bias_std * p.gnss_bias_std,
                      vertical * vertical) *
      (scale * scale);
  const auto before = vertices.lower_bound(k);  // windows are met in time order
  // A fix mode whose accuracy differs by more than 1.5x (RTK lost or regained) has a bias of its
  // own: it starts afresh instead of continuing the previous window's.
  bool fresh = before == vertices.begin();
  if (!fresh) {
    const double r = scale / session.gnss_bias_scales.at(std::prev(before)->first);
    fresh = !(r > 1.0 / 1.5 && r < 1.5);
  }
  if (fresh) {
    graph.addVertexPointXYZ(id, Eigen::Vector3d::Zero());
    graph.addPriorPointXYZ(id, Eigen::Vector3d::Zero(), var.cwiseInverse().asDiagonal());
  } else {
    // b_k / s_k = φ·b_j / s_j + w, var(w) = σ²(1 − φ²): the stationary process of the bias over
    // its deviation σ s (a receiver whose accuracy changes) across the windows between (an
    // outage may skip some).
    const auto& [j, prev] = *std::prev(before);
    const double window = std::max(p.gnss_bias_window, 1e-3);
    const double phi = p.gnss_bias_tau > 0.0 ? std::exp(-(k - j) * window / p.gnss_bias_tau) : 0.0;
    const double step = phi * scale / session.gnss_bias_scales.at(j);
    const Eigen::Vector3d step_var = var * std::max(1.0 - phi * phi, 1e-6);
    graph.addVertexPointXYZ(id,
                            step * graph.vertexPointXYZ(prev).value_or(Eigen::Vector3d::Zero()));
    graph.addEdgePointXYZGaussMarkov(prev, id, step, step_var.cwiseInverse().asDiagonal());
  }
  vertices.emplace(k, id);
  session.gnss_bias_scales.emplace(k, scale);
  return id;
}

int BackendState::odometryScaleVertex(uint32_t session_id, double accum_distance,
                                      const OdometryEdgeParams& p) {
  auto& vertices = sessions[session_id].scale_vertices;
  const int k = odometryScaleWindow(accum_distance, p);
  const auto found = vertices.find(k);
  if (found != vertices.end()) return found->second;
  const int id = GraphBackend::kScaleVertexTop -
                 static_cast<int>(session_id) * GraphBackend::kSessionWindows - k;
  const auto before = vertices.lower_bound(k);
  if (before == vertices.begin()) {
    graph.addVertexScale(id, 1.0);
    graph.addPriorScale(id, 1.0, 1.0 / (p.odometry_scale_std * p.odometry_scale_std));
  } else {
    // A re-anchored or skipped stretch leaves windows out: the walk spans them all.
    const auto& [j, prev] = *std::prev(before);
    const double var = std::max(k - j, 1) * p.odometry_scale_walk_std * p.odometry_scale_walk_std;
    graph.addVertexScale(id, graph.vertexScale(prev).value_or(1.0));
    graph.addEdgeScaleDifference(prev, id, 0.0, 1.0 / var);
  }
  vertices.emplace(k, id);
  return id;
}

bool BackendState::covered(const Eigen::Vector2d& position) const {
  for (const auto& [center, radius] : coverage)
    if ((position - center).norm() <= radius) return true;
  return false;
}

void BackendState::holdVertex(int vid, std::vector<int>& fixed_now) {
  if (graph.isFixed(vid)) return;
  graph.setFixed(vid, true);
  fixed_now.push_back(vid);
}

std::vector<int> BackendState::fixRobots() {
  std::vector<int> fixed_now;
  auto fix = [&](int vid) { holdVertex(vid, fixed_now); };
  for (const auto& [id, kf] : keyframes) fix(static_cast<int>(id));
  // The odometry's scale belongs to the trajectory: with every pose fixed it has nothing to do.
  for (const auto& [id, session] : sessions)
    for (const auto& [window, vid] : session.scale_vertices) fix(vid);
  return fixed_now;
}

std::vector<int> BackendState::holdOutsideWindow(uint64_t window_start,
                                                 const OdometryEdgeParams& odometry,
                                                 const GnssParams& gnss) {
  std::vector<int> fixed_now;
  auto hold = [&](int vid) { holdVertex(vid, fixed_now); };
  for (auto it = keyframes.begin(); it != keyframes.end() && it->first < window_start; ++it)
    hold(static_cast<int>(it->first));
  // Scales and biases of windows that end before the first free keyframe touch only held poses:
  // a free one would keep every old odometry edge or fix in the problem (the window would save
  // nothing).
  auto holdBefore = [&](const std::map<int, int>& windows, int first_free) {
    for (const auto& [window, vid] : windows)
      if (window < first_free) hold(vid);
  };
  // A session whose keyframes are all held has every window held; the others from their first
  // free keyframe's windows.
  std::map<uint32_t, const KeyframeState*> first_free;
  for (auto it = keyframes.lower_bound(window_start); it != keyframes.end(); ++it)
    first_free.emplace(it->second.session, &it->second);
  for (const auto& [id, session] : sessions) {
    const auto free = first_free.find(id);
    const bool all_held = free == first_free.end();
    if (odometry.odometry_scale_window > 0.0)
      holdBefore(session.scale_vertices,
                 all_held ? GraphBackend::kSessionWindows
                          : odometryScaleWindow(free->second->accum_distance, odometry));
    holdBefore(session.gnss_bias_vertices,
               all_held ? GraphBackend::kSessionWindows
                        : gnssBiasWindow(session, free->second->stamp, gnss));
  }
  std::set<int64_t> seen_from_window;
  for (const auto& e : building_edges)
    if (e.keyframe >= window_start) seen_from_window.insert(e.building);
  for (const auto& [bid, b] : buildings)
    if (b.vertex_id >= 0 && !seen_from_window.count(bid)) hold(b.vertex_id);
  return fixed_now;
}

std::vector<int> BackendState::holdOutsideTile(const std::set<uint64_t>& free_keyframes,
                                               const std::set<int64_t>& free_buildings,
                                               const OdometryEdgeParams& odometry,
                                               const GnssParams& gnss) {
  std::vector<int> fixed_now;
  auto hold = [&](int vid) { holdVertex(vid, fixed_now); };
  std::map<uint32_t, std::set<int>> free_scale, free_bias;
  for (const auto& [id, kf] : keyframes) {
    if (!free_keyframes.count(id)) {
      hold(static_cast<int>(id));
      continue;
    }
    free_scale[kf.session].insert(odometryScaleWindow(kf.accum_distance, odometry));
    free_bias[kf.session].insert(gnssBiasWindow(sessions[kf.session], kf.stamp, gnss));
  }
  for (const auto& [id, session] : sessions) {
    for (const auto& [window, vid] : session.scale_vertices)
      if (!free_scale[id].count(window)) hold(vid);
    for (const auto& [window, vid] : session.gnss_bias_vertices)
      if (!free_bias[id].count(window)) hold(vid);
  }
  for (const auto& [bid, b] : buildings)
    if (b.vertex_id >= 0 && !free_buildings.count(bid)) hold(b.vertex_id);
  return fixed_now;
}

void BackendState::release(const std::vector<int>& held, const OsmPriorParams& p) {
  std::set<int> stay;
  for (const auto& [bid, b] : buildings)
    if (b.vertex_id >= 0 && heldAtPrior(b, p)) stay.insert(b.vertex_id);
  for (int vid : held)
    if (!stay.count(vid)) graph.setFixed(vid, false);
}

void BackendState::readRobotPoses() {
  for (auto& [id, kf] : keyframes)
    if (auto pose = graph.vertexSE3(static_cast<int>(id))) kf.map_pose = *pose;
}

void BackendState::readBuildingPoses(const OsmPriorParams& p) {
  for (auto& [bid, b] : buildings) {
    if (auto pose = graph.vertexSE2(b.vertex_id))
      b.pose = *pose;
    else
      b.pose = predictedPose(b, p);
  }
}

void BackendState::rotateTrajectory(double dyaw) {
  const Eigen::Vector2d pivot =
      keyframes.empty()
          ? Eigen::Vector2d::Zero()
          : Eigen::Vector2d(keyframes.begin()->second.map_pose.translation().head<2>());
  const Eigen::Vector2d shift = pivot - Pose2(0.0, 0.0, dyaw).rotation() * pivot;
  const Eigen::Isometry3d rot = isometryFromPlanar(Pose2(shift.x(), shift.y(), dyaw));
  for (auto& [id, kf] : keyframes) {
    kf.map_pose = rot * kf.map_pose;
    graph.setVertexSE3(static_cast<int>(id), kf.map_pose);
  }
  map_to_odom = rot * map_to_odom;
}

RobustKernel kernelNamed(const std::string& name, double width) {
  if (name == "huber") return RobustKernel::huber(width);
  if (name == "cauchy") return RobustKernel::cauchy(width);
  return RobustKernel::none();
}

Eigen::Matrix3d rotateInformation(const Eigen::Matrix3d& info_map, double frame_yaw) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  R.topLeftCorner<2, 2>() = Pose2(0, 0, frame_yaw).rotation();
  return R.transpose() * info_map * R;
}

Eigen::Isometry3d attitudeMeasurement(const Eigen::Isometry3d& pose, double roll, double pitch) {
  const double yaw = planarPose(pose).theta;
  Eigen::Isometry3d z = Eigen::Isometry3d::Identity();
  z.linear() = rotationFromRollPitchYaw(roll, pitch, yaw);
  z.translation() = pose.translation();
  return z;
}

Matrix6d attitudeInformation(double std_rad) {
  Matrix6d info = Matrix6d::Identity() * 1e-9;  // positive definite; effectively unconstrained
  info(3, 3) = info(4, 4) = 1.0 / (std_rad * std_rad);
  return info;
}

}  // namespace osm_graph_slam
