#include "building_constraints.h"

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/osm/building_set.h"

namespace osm_graph_slam {
namespace {

/// The separated pose moved `clearance` further along the separating translation. A flush target
/// leaves no room: when a building is separated from two neighbours at once, the optimiser
/// compromises between the hard edges and the outlines keep touching by a few millimetres.
Pose2 withClearance(const Pose2& separated, const Pose2& before, double clearance) {
  const Eigen::Vector2d move = separated.translation() - before.translation();
  if (clearance <= 0.0 || move.norm() < 1e-6) return separated;
  const Eigen::Vector2d t = separated.translation() + clearance * move.normalized();
  return {t.x(), t.y(), separated.theta};
}

}  // namespace

size_t BuildingConstraints::gateBuildingEdges(BackendState& s, BackendUpdateReport& report) const {
  // Robot<->building edges that disagree with the building as all its other observations place
  // it (after phase 2) are wrong associations: removed before they bend the trajectory.
  size_t removed = 0;
  std::vector<BuildingEdgeRecord> keep;
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
    if (BackendState::heldAtPrior(b->second, prior_) && b->second.vertex_id >= 0) {
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

void BuildingConstraints::findNewContacts(const BackendState& s) {
  if (shared_walls_searched_ == s.buildings.size()) return;
  shared_walls_searched_ = s.buildings.size();
  std::vector<int64_t> ids;
  std::vector<Polygon2> outlines;
  for (const auto& [bid, b] : s.buildings) {
    ids.push_back(bid);
    outlines.push_back(b.prior.outline_enu);
  }
  for (const auto& c : findBuildingContacts(outlines, params_.shared_walls))
    shared_walls_.try_emplace(std::make_pair(ids[c.a], ids[c.b]), SharedWall{c, false});
}

void BuildingConstraints::addSharedWallEdges(BackendState& s, BackendUpdateReport& report) {
  // Pairs join the graph once one of the two buildings is in it; the other follows (and so on
  // along a row), so a building nobody saw moves with the neighbour it shares a wall with.
  findNewContacts(s);
  const double info = 1.0 / (params_.shared_wall_std * params_.shared_wall_std);
  const EdgeOptions options{1, RobustKernel::huber(params_.shared_wall_kernel_width)};
  for (bool changed = true; changed;) {
    changed = false;
    for (auto& [key, wall] : shared_walls_) {
      if (wall.tied) continue;
      BuildingState& a = s.buildings.at(key.first);
      BuildingState& b = s.buildings.at(key.second);
      if (a.vertex_id < 0 && b.vertex_id < 0) continue;
      if (prior_.unobserved_buildings_fixed && (a.observations == 0 || b.observations == 0))
        continue;  // tied once both are observed
      const BuildingContact& c = wall.contact;
      const Pose2& pa = a.prior.reference_pose;
      const Pose2& pb = b.prior.reference_pose;
      const Eigen::Vector2d normal = pb.rotation().transpose() * c.b_normal;
      const double offset = normal.dot(pb.inverse().transform(c.b_point));
      const int va = s.buildingVertex(a, mode_, prior_), vb = s.buildingVertex(b, mode_, prior_);
      for (const auto& end : c.a_ends)
        s.graph.addEdgeSE2PointOnLine(va, vb, pa.inverse().transform(end), normal, offset, info,
                                      options);
      wall.tied = true;
      changed = true;
    }
  }
  for (const auto& [key, wall] : shared_walls_) report.shared_walls += wall.tied ? 1 : 0;
}

void BuildingConstraints::removeOverlapEdges(BackendState& s) {
  for (int edge : overlap_edges_) s.graph.removeEdge(edge);
  overlap_edges_.clear();
}

bool BuildingConstraints::addSeparationEdge(BackendState& s, BuildingState* a, BuildingState* b) {
  // Move the less observed building (a building nobody saw has only its OSM prior).
  if (a->observations > b->observations) std::swap(a, b);
  const LineMatchResult sep = matcher_.removeOverlap(a->local_outline, a->pose,
                                                     transformPolygon(b->local_outline, b->pose));
  if (!sep.success) return false;
  const Pose2 target = withClearance(sep.transform, a->pose, params_.overlap_clearance);
  const Pose2 z = target.inverse() * b->pose;  // relPose of Alg. 3.2, line 10
  const Eigen::Matrix3d info = Eigen::Matrix3d::Identity() * params_.overlap_information;
  const int edge =
      s.graph.addEdgeSE2(s.buildingVertex(*a, mode_, prior_), s.buildingVertex(*b, mode_, prior_),
                         z, info, EdgeOptions{2, {}});
  if (edge >= 0) overlap_edges_.push_back(edge);
  // Two buildings nobody saw whose priors overlap: the prior itself is wrong, one must move.
  if (b->observations == 0 && mode_ != OsmMode::kPrior) s.graph.setFixed(a->vertex_id, false);
  return edge >= 0;
}

void BuildingConstraints::resolveOverlaps(BackendState& s, BackendUpdateReport& report) {
  // Algorithm 3.2: hard building<->building edges from the overlap-removal matcher, re-optimised
  // at level 2 (robots stay fixed), until no outline intersects or the iterations run out.
  // Separating two buildings says nothing about where the map as a whole sits.
  const bool datum = s.graph.hasVertex(GraphBackend::kOsmDatumVertex);
  if (datum) s.graph.setFixed(GraphBackend::kOsmDatumVertex, true);
  std::vector<BuildingState*> order;
  std::vector<Building> outlines;
  for (auto& [bid, b] : s.buildings) {
    order.push_back(&b);
    outlines.push_back(b.corrected());
  }
  auto overlaps = findOverlappingBuildings(outlines, params_.overlap_min_area);
  for (int iter = 0; iter < params_.overlap_max_iterations && !overlaps.empty(); ++iter) {
    size_t added = 0;
    for (const auto& [i, j] : overlaps) added += addSeparationEdge(s, order[i], order[j]) ? 1 : 0;
    report.overlap_iterations = static_cast<size_t>(iter + 1);
    report.overlap_edges += added;
    if (added == 0) break;
    report.overlap = s.graph.optimize(2, optimizer_);
    outlines.clear();
    for (BuildingState* b : order) {
      if (auto pose = s.graph.vertexSE2(b->vertex_id)) b->pose = *pose;
      outlines.push_back(b->corrected());
    }
    overlaps = findOverlappingBuildings(outlines, params_.overlap_min_area);
  }
  if (datum) s.graph.setFixed(GraphBackend::kOsmDatumVertex, false);
  if (!overlaps.empty() && params_.overlap_projection_max_translation > 0.0) {
    const size_t before = overlaps.size();
    overlaps = projectOutOfOverlaps(s, order, outlines, std::move(overlaps));
    report.overlaps_projected += before - overlaps.size();
  }
  report.overlaps_remaining = overlaps.size();
}

std::vector<std::pair<size_t, size_t>> BuildingConstraints::projectOutOfOverlaps(
    BackendState& s, const std::vector<BuildingState*>& order, std::vector<Building>& outlines,
    std::vector<std::pair<size_t, size_t>> overlaps) const {
  // A building's pose after the hard edges is where its evidence puts it; the non-overlap
  // constraint then asks for the nearest pose that satisfies it: with an isotropic prior, the
  // shortest translation (the edges' compromise never reaches it when two neighbours push).
  // A held building (at its prior, or outside the window) stays where it is.
  auto movable = [&](size_t k) {
    return order[k]->vertex_id >= 0 && !s.graph.isFixed(order[k]->vertex_id);
  };
  for (int pass = 0; pass < 3 && !overlaps.empty(); ++pass) {
    for (const auto& [i, j] : overlaps) {
      // The less observed of the two, unless it is held.
      const bool i_first = order[i]->observations <= order[j]->observations;
      const size_t first = i_first ? i : j, second = i_first ? j : i;
      if (!movable(first) && !movable(second)) continue;
      const size_t mover = movable(first) ? first : second;
      BuildingState& b = *order[mover];
      const std::optional<Eigen::Vector2d> t = clearingTranslation(mover, outlines);
      if (!t) continue;
      b.pose = Pose2(b.pose.x + t->x(), b.pose.y + t->y(), b.pose.theta);
      s.graph.setVertexSE2(b.vertex_id, b.pose);
      outlines[mover] = b.corrected();
    }
    overlaps = findOverlappingBuildings(outlines, params_.overlap_min_area);
  }
  return overlaps;
}

std::optional<Eigen::Vector2d> BuildingConstraints::clearingTranslation(
    size_t mover, const std::vector<Building>& outlines) const {
  const double reach = params_.overlap_projection_max_translation;
  const Polygon2& outline = outlines[mover].outline_enu;
  std::vector<const Polygon2*> near;
  {
    std::vector<const Polygon2*> all;
    for (const Building& b : outlines) all.push_back(&b.outline_enu);
    for (const auto& [a, b] : nearbyPolygonPairs(all, reach)) {
      if (a == mover) near.push_back(all[b]);
      if (b == mover) near.push_back(all[a]);
    }
  }
  const double limit = 0.5 * params_.overlap_min_area;
  auto clear = [&](const Eigen::Vector2d& t) {
    Polygon2 moved = outline;
    for (auto& v : moved) v += t;
    for (const Polygon2* other : near)
      if (polygonOverlapArea(moved, *other) > limit) return false;
    return true;
  };
  constexpr double kStep = 0.01;  // [m]
  constexpr int kDirections = 36;
  for (double d = kStep; d <= reach + 1e-9; d += kStep) {
    for (int k = 0; k < kDirections; ++k) {
      const double a = 2.0 * M_PI * k / kDirections;
      const Eigen::Vector2d dir(std::cos(a), std::sin(a));
      if (clear(d * dir)) return (d + params_.overlap_clearance) * dir;
    }
  }
  return std::nullopt;
}

}  // namespace osm_graph_slam
