#include "osm_graph_slam/landmarks/landmark_extraction.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace osm_graph_slam {

namespace {

/// Lowest z per ground cell on a dense grid over +-max_range; cells whose lowest point cannot be
/// ground (more than 1.5 m above the ground plane under the sensor) are left out: far cells
/// behind trunks see only the trunks. The ground of a cell is the lowest of the 3x3 cells around
/// (else the 5x5, else the plane under the sensor), computed once per cell.
class GroundGrid {
 public:
  GroundGrid(const std::vector<Eigen::Vector3d>& pts, double cell, double max_range,
             double sensor_height)
      : cell_(cell), half_(int(std::ceil(max_range / cell)) + 1), n_(2 * half_ + 1) {
    const double fallback = -sensor_height;
    std::vector<double> min_z(size_t(n_) * n_, kEmpty);
    for (const auto& p : pts) {
      if (p.z() > fallback + 1.5) continue;
      const int i = index(p.x(), p.y());
      if (i >= 0) min_z[i] = std::min(min_z[i], p.z());
    }
    ground_.assign(size_t(n_) * n_, fallback);
    for (int y = 0; y < n_; ++y)
      for (int x = 0; x < n_; ++x) {
        for (int r = 1; r <= 2; ++r) {
          double best = kEmpty;
          for (int dy = -r; dy <= r; ++dy)
            for (int dx = -r; dx <= r; ++dx) {
              const int xx = x + dx, yy = y + dy;
              if (xx >= 0 && yy >= 0 && xx < n_ && yy < n_)
                best = std::min(best, min_z[size_t(yy) * n_ + xx]);
            }
          if (best < kEmpty) {
            ground_[size_t(y) * n_ + x] = best;
            break;
          }
        }
      }
  }
  double height(double x, double y) const {
    const int i = index(x, y);
    return i >= 0 ? ground_[i] : ground_[size_t(half_) * n_ + half_];
  }

 private:
  static constexpr double kEmpty = 1e300;
  int index(double x, double y) const {
    const int cx = int(std::floor(x / cell_)) + half_, cy = int(std::floor(y / cell_)) + half_;
    if (cx < 0 || cy < 0 || cx >= n_ || cy >= n_) return -1;
    return cy * n_ + cx;
  }
  double cell_;
  int half_, n_;
  std::vector<double> ground_;
};

struct BandPoint {
  Eigen::Vector2d xy;
  double h;  ///< above the ground
};

struct Scratch {
  std::vector<Eigen::Vector3d> pts;
  std::vector<BandPoint> band;
  std::vector<int> cell_of, first, order, fill;
  std::vector<uint8_t> visited;
};

}  // namespace

std::vector<Landmark> extractLandmarks(const PointCloud& cloud,
                                       const LandmarkExtractionParams& params) {
  std::vector<Landmark> out;
  // Scratch buffers kept per thread: fresh multi-megabyte vectors per keyframe cost more in page
  // faults than the extraction itself (perf on the KITTI 0005 scans).
  thread_local Scratch scratch;
  std::vector<Eigen::Vector3d>& pts = scratch.pts;
  pts.clear();
  const double r0 = params.min_range * params.min_range, r1 = params.max_range * params.max_range;
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const double d2 = double(p.x) * p.x + double(p.y) * p.y;
    if (d2 < r0 || d2 > r1) continue;
    pts.emplace_back(p.x, p.y, p.z);
  }
  if (pts.empty()) return out;
  const GroundGrid ground(pts, params.ground_cell, params.max_range, params.sensor_height);

  // Trunk band points bucketed by 2D occupancy cell (a dense grid over +-max_range: a city
  // keyframe has tens of thousands of wall points in the band, and a hash map of per-cell
  // vectors cost more than the rest of the extraction).
  const double cc = params.cluster_cell;
  const int half = int(std::ceil(params.max_range / cc)) + 1, n = 2 * half + 1;
  std::vector<BandPoint>& band = scratch.band;
  std::vector<int>& cell_of = scratch.cell_of;
  band.clear();
  cell_of.clear();
  for (const auto& p : pts) {
    const double h = p.z() - ground.height(p.x(), p.y());
    if (h < params.band_min || h > params.band_max) continue;
    const int cx = int(std::floor(p.x() / cc)) + half, cy = int(std::floor(p.y() / cc)) + half;
    if (cx < 0 || cy < 0 || cx >= n || cy >= n) continue;
    band.push_back({p.head<2>(), h});
    cell_of.push_back(cy * n + cx);
  }
  // Counting sort: cell c holds order[first[c] .. first[c + 1]).
  std::vector<int>& first = scratch.first;
  first.assign(size_t(n) * n + 1, 0);
  for (int c : cell_of) ++first[c + 1];
  for (size_t c = 1; c < first.size(); ++c) first[c] += first[c - 1];
  std::vector<int>& order = scratch.order;
  std::vector<int>& fill = scratch.fill;
  order.resize(band.size());
  fill.assign(first.begin(), first.end() - 1);
  for (int i = 0; i < int(band.size()); ++i) order[fill[cell_of[i]]++] = i;
  const auto occupied = [&](int c) { return first[c + 1] > first[c]; };
  // A component whose points span more than this along x or y cannot be a trunk: one of its
  // extents across or along the viewing ray exceeds 2 max_radius (checked below).
  const double max_span = 2.0 * std::sqrt(2.0) * params.max_radius;
  // 8-connected components of occupied cells.
  std::vector<uint8_t>& visited = scratch.visited;
  visited.assign(size_t(n) * n, 0);
  const double slice = params.slice_height;
  const int slices = std::max(1, int(std::round((params.band_max - params.band_min) / slice)));
  std::vector<int> stack, members;
  for (const int start : cell_of) {
    if (visited[start]) continue;
    visited[start] = 1;
    stack.assign(1, start);
    members.clear();
    int x_lo = n, x_hi = -1, y_lo = n, y_hi = -1;
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      members.insert(members.end(), order.begin() + first[c], order.begin() + first[c + 1]);
      const int x = c % n, y = c / n;
      x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x), y_lo = std::min(y_lo, y),
      y_hi = std::max(y_hi, y);
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= n || yy >= n) continue;
          const int nc = yy * n + xx;
          if (!visited[nc] && occupied(nc)) {
            visited[nc] = 1;
            stack.push_back(nc);
          }
        }
    }
    // Points in the first and last cells of a span of k cells are more than (k - 2) cells apart.
    if ((std::max(x_hi - x_lo, y_hi - y_lo) - 1) * cc >= max_span) continue;
    if (int(members.size()) < params.min_points) continue;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (int i : members) mean += band[i].xy;
    mean /= double(members.size());
    const double range = mean.norm();
    if (range < 1e-6) continue;
    // Vertical coverage of the part of the band the highest beam reaches at this range.
    const double ground_z = ground.height(mean.x(), mean.y());
    const double visible_top = std::min(
        params.band_max, params.sensor_above_origin +
                             range * std::tan(params.max_elevation_deg * M_PI / 180.0) - ground_z);
    if (visible_top - params.band_min < 0.6) continue;  // less than 0.6 m of the band in view
    const int visible_slices =
        std::min(slices, int(std::floor((visible_top - params.band_min) / slice)));
    if (visible_slices < 1) continue;
    std::vector<bool> filled(slices, false);
    for (int i : members)
      filled[std::clamp(int((band[i].h - params.band_min) / slice), 0, slices - 1)] = true;
    const double coverage =
        std::min(1.0, double(std::count(filled.begin(), filled.begin() + visible_slices, true)) /
                          visible_slices);
    if (coverage < params.min_vertical_coverage) continue;
    // Width across the viewing ray = the diameter; the centre lies one radius behind the
    // nearest point along the ray (only the near side of a trunk is seen).
    const Eigen::Vector2d u = mean / range, t(-u.y(), u.x());
    double t_min = 1e300, t_max = -1e300, u_min = 1e300, u_max = -1e300;
    for (int i : members) {
      const double a = band[i].xy.dot(t), b = band[i].xy.dot(u);
      t_min = std::min(t_min, a);
      t_max = std::max(t_max, a);
      u_min = std::min(u_min, b);
      u_max = std::max(u_max, b);
    }
    const double radius = std::max(params.min_radius, 0.5 * (t_max - t_min));
    if (radius > params.max_radius || (u_max - u_min) > 2.0 * params.max_radius) continue;
    Landmark lm;
    lm.radius = radius;
    lm.center = u * (u_min + radius) + t * (0.5 * (t_min + t_max));
    lm.points = int(members.size());
    lm.vertical_coverage = coverage;
    lm.confidence = coverage * (1.0 - std::exp(-double(members.size()) / 15.0));
    if (lm.confidence >= params.min_confidence) out.push_back(lm);
  }
  // Deterministic order (the hash map's is not): by angle then range.
  std::sort(out.begin(), out.end(), [](const Landmark& a, const Landmark& b) {
    const double aa = std::atan2(a.center.y(), a.center.x()),
                 ab = std::atan2(b.center.y(), b.center.x());
    if (aa != ab) return aa < ab;
    return a.center.squaredNorm() < b.center.squaredNorm();
  });
  return out;
}

std::vector<Eigen::Vector2d> landmarkCenters(const std::vector<Landmark>& landmarks) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(landmarks.size());
  for (const auto& l : landmarks) out.push_back(l.center);
  return out;
}

}  // namespace osm_graph_slam
