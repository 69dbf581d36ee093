#include "osm_graph_slam/loop/scan_context.h"

#include <algorithm>
#include <cmath>

namespace osm_graph_slam {
namespace {

int wrapIndex(int i, int n) {
  return ((i % n) + n) % n;
}

void computeKeys(ScanContext& sc) {
  const int rings = static_cast<int>(sc.cells.rows());
  const int sectors = static_cast<int>(sc.cells.cols());
  sc.ring_key.resize(rings);
  for (int r = 0; r < rings; ++r) {
    int occupied = 0;
    for (int s = 0; s < sectors; ++s) occupied += sc.cells(r, s) > 0.f ? 1 : 0;
    sc.ring_key[r] = static_cast<float>(occupied) / static_cast<float>(sectors);
  }
  sc.sector_key = sc.cells.colwise().mean().transpose();
  sc.column_norms = sc.cells.colwise().norm().transpose();
  sc.occupied_cells = static_cast<int>((sc.cells.array() > 0.f).count());
}

}  // namespace

ScanContext scanContextFromCells(const Eigen::MatrixXf& cells) {
  ScanContext sc;
  sc.cells = cells;
  computeKeys(sc);
  return sc;
}

namespace {

/// In the caller's precision: the LiDAR descriptor bins float points in float (the test of exact
/// sector rotations depends on it), the radar one double points.
template <typename T>
bool cellOf(T x, T y, const ScanContextParams& params, int* ring, int* sector) {
  const int rings = std::max(1, params.num_rings);
  const int sectors = std::max(1, params.num_sectors);
  const double ring_width = params.max_radius / rings;
  const double sector_width = 2.0 * M_PI / sectors;
  const T range = std::hypot(x, y);
  if (!(range < params.max_radius) || range < params.min_radius) return false;
  *ring = std::min(rings - 1, static_cast<int>(range / ring_width));
  const double azimuth = std::atan2(y, x) + M_PI;  // [0, 2 pi]
  *sector = std::min(sectors - 1, static_cast<int>(azimuth / sector_width));
  return true;
}

}  // namespace

bool scanContextCell(double x, double y, const ScanContextParams& params, int* ring, int* sector) {
  return cellOf(x, y, params, ring, sector);
}

bool scanContextCell(float x, float y, const ScanContextParams& params, int* ring, int* sector) {
  return cellOf(x, y, params, ring, sector);
}

ScanContext computeScanContext(const PointCloud& cloud, const ScanContextParams& params) {
  ScanContext sc;
  sc.cells = Eigen::MatrixXf::Zero(std::max(1, params.num_rings), std::max(1, params.num_sectors));
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const double height =
        std::min(static_cast<double>(p.z) + params.sensor_height, params.max_height);
    // Ground returns: noise, no structure (tested first: no atan2 for the ground's many points).
    if (height < params.min_height) continue;
    int ring, sector;
    if (!scanContextCell(p.x, p.y, params, &ring, &sector)) continue;
    float& cell = sc.cells(ring, sector);
    cell = std::max(cell, static_cast<float>(height));
  }
  computeKeys(sc);
  return sc;
}

double scanContextDistanceAtShift(const ScanContext& query, const ScanContext& candidate,
                                  int shift) {
  const int sectors = static_cast<int>(query.cells.cols());
  if (sectors == 0 || candidate.cells.cols() != sectors ||
      candidate.cells.rows() != query.cells.rows()) {
    return 1.0;
  }
  double similarity = 0.0;
  int compared = 0;
  for (int j = 0; j < sectors; ++j) {
    const int jc = wrapIndex(j + shift, sectors);
    const float nq = query.column_norms[j];
    const float nc = candidate.column_norms[jc];
    if (nq <= 0.f && nc <= 0.f) continue;  // both empty: no evidence either way
    ++compared;
    if (nq <= 0.f || nc <= 0.f) continue;  // one side empty: similarity 0
    similarity += query.cells.col(j).dot(candidate.cells.col(jc)) / (nq * nc);
  }
  if (compared == 0) return 1.0;
  return 1.0 - similarity / compared;
}

int sectorKeyShift(const ScanContext& query, const ScanContext& candidate) {
  const int sectors = static_cast<int>(query.sector_key.size());
  if (sectors == 0 || candidate.sector_key.size() != sectors) return 0;
  int best_shift = 0;
  float best_cost = std::numeric_limits<float>::max();
  for (int shift = 0; shift < sectors; ++shift) {
    // Summed in the order of j as before, without a modulo per term (two loops, no wrap).
    float cost = 0.f;
    const int wrap = sectors - shift;
    for (int j = 0; j < wrap; ++j)
      cost += std::abs(query.sector_key[j] - candidate.sector_key[j + shift]);
    for (int j = wrap; j < sectors; ++j)
      cost += std::abs(query.sector_key[j] - candidate.sector_key[j - wrap]);
    if (cost < best_cost) {
      best_cost = cost;
      best_shift = shift;
    }
  }
  return best_shift;
}

ScanContextMatch matchScanContexts(const ScanContext& query, const ScanContext& candidate,
                                   const ScanContextParams& params) {
  ScanContextMatch best;
  const int sectors = static_cast<int>(query.cells.cols());
  if (sectors == 0) return best;
  int first = 0;
  int last = sectors - 1;
  int center = 0;
  if (params.sector_search_window >= 0 && 2 * params.sector_search_window + 1 < sectors) {
    center = sectorKeyShift(query, candidate);
    first = -params.sector_search_window;
    last = params.sector_search_window;
  }
  for (int offset = first; offset <= last; ++offset) {
    const int shift = wrapIndex(center + offset, sectors);
    const double d = scanContextDistanceAtShift(query, candidate, shift);
    if (d < best.distance || offset == first) {
      best.distance = d;
      best.shift = shift;
    }
  }
  const double sector_width = 2.0 * M_PI / sectors;
  double yaw = best.shift * sector_width;
  if (yaw > M_PI) yaw -= 2.0 * M_PI;
  best.yaw = yaw;
  return best;
}

}  // namespace osm_graph_slam
