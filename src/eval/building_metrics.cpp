#include "osm_graph_slam/eval/building_metrics.h"

#include "osm_graph_slam/lines/line_geometry.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace osm_graph_slam {
namespace {

size_t lowestXVertex(const Polygon2& ring) {
  size_t best = 0;
  for (size_t i = 1; i < ring.size(); ++i)
    if (ring[i].x() < ring[best].x()) best = i;
  return best;
}

/// Rotation angle of the least-squares 2D rigid fit mapping a onto b (corresponding points).
double fitRotation(const Polygon2& a, const Polygon2& b) {
  Eigen::Vector2d ma = Eigen::Vector2d::Zero(), mb = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= static_cast<double>(a.size());
  mb /= static_cast<double>(b.size());
  double s_cos = 0.0, s_sin = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector2d p = a[i] - ma, q = b[i] - mb;
    s_cos += p.dot(q);
    s_sin += p.x() * q.y() - p.y() * q.x();
  }
  return std::atan2(s_sin, s_cos);
}

}  // namespace

BuildingErrors evaluateBuildings(const std::vector<Building>& estimate,
                                 const std::vector<Building>& truth) {
  BuildingErrors out;
  std::unordered_map<int64_t, const Building*> truth_by_id;
  for (const auto& b : truth) truth_by_id[b.id] = &b;
  double corner_sum = 0.0, heading_sum = 0.0, vertex_sum = 0.0;
  size_t vertex_count = 0;
  std::vector<Eigen::Vector2d> corner_offsets;
  for (const auto& est : estimate) {
    const auto it = truth_by_id.find(est.id);
    if (it == truth_by_id.end()) continue;
    const Polygon2& t = it->second->outline_enu;
    const Polygon2& e = est.outline_enu;
    if (t.size() != e.size() || t.size() < 3) {
      ++out.vertex_mismatch;
      continue;
    }
    ++out.matched;
    const size_t ref = lowestXVertex(t);
    corner_offsets.push_back(e[ref] - t[ref]);
    const double corner = corner_offsets.back().norm();
    corner_sum += corner;
    out.max_corner_error = std::max(out.max_corner_error, corner);
    heading_sum += std::abs(fitRotation(e, t)) * 180.0 / M_PI;
    for (size_t i = 0; i < t.size(); ++i) vertex_sum += (e[i] - t[i]).norm();
    vertex_count += t.size();
  }
  if (out.matched > 0) {
    out.mean_corner_error = corner_sum / static_cast<double>(out.matched);
    out.mean_heading_error_deg = heading_sum / static_cast<double>(out.matched);
    out.mean_vertex_error = vertex_sum / static_cast<double>(vertex_count);
    Eigen::Vector2d common = Eigen::Vector2d::Zero();
    for (const auto& d : corner_offsets) common += d;
    common /= static_cast<double>(corner_offsets.size());
    out.common_offset = common.norm();
    for (const auto& d : corner_offsets) out.mean_corner_error_shape += (d - common).norm();
    out.mean_corner_error_shape /= static_cast<double>(corner_offsets.size());
  }
  return out;
}

}  // namespace osm_graph_slam
