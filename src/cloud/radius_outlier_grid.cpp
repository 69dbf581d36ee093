#include "osm_graph_slam/cloud/radius_outlier_grid.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace osm_graph_slam {
namespace {

using CellKey = uint64_t;

/// 21 bits per axis (cells of >= 1 cm cover +-10 km): plenty for one scan.
CellKey packCell(int64_t x, int64_t y, int64_t z) {
  constexpr int64_t kBias = int64_t(1) << 20;
  constexpr uint64_t kMask = (uint64_t(1) << 21) - 1;
  return (uint64_t(x + kBias) & kMask) | ((uint64_t(y + kBias) & kMask) << 21) |
         ((uint64_t(z + kBias) & kMask) << 42);
}

/// Points sorted by cell, and per cell the range [begin, end) into that order.
struct CellGrid {
  std::vector<uint32_t> order;
  std::unordered_map<CellKey, std::pair<uint32_t, uint32_t>> cells;
  std::vector<Eigen::Vector3i> cell_of;  ///< per input point
};

CellGrid buildGrid(const PointCloud& cloud, double cell) {
  CellGrid grid;
  const size_t n = cloud.size();
  grid.cell_of.resize(n);
  std::vector<std::pair<CellKey, uint32_t>> keyed(n);
  const double inv = 1.0 / cell;
  for (size_t i = 0; i < n; ++i) {
    const auto& p = cloud.points[i];
    const Eigen::Vector3i c(int(std::floor(p.x * inv)), int(std::floor(p.y * inv)),
                            int(std::floor(p.z * inv)));
    grid.cell_of[i] = c;
    keyed[i] = {packCell(c.x(), c.y(), c.z()), uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  grid.order.resize(n);
  grid.cells.reserve(n);
  for (size_t i = 0; i < n;) {
    size_t j = i;
    while (j < n && keyed[j].first == keyed[i].first) {
      grid.order[j] = keyed[j].second;
      ++j;
    }
    grid.cells.emplace(keyed[i].first, std::make_pair(uint32_t(i), uint32_t(j)));
    i = j;
  }
  return grid;
}

/// Squared distance summed axis by axis in float, as FLANN's L2_Simple does.
float squaredDistance(const PointT& a, const PointT& b) {
  float d = 0.0f;
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  d += dx * dx;
  d += dy * dy;
  d += dz * dz;
  return d;
}

}  // namespace

std::vector<uint8_t> radiusInlierMask(const PointCloud& cloud, double radius, int min_neighbors,
                                      int num_threads) {
  std::vector<uint8_t> keep(cloud.size(), 0);
  if (cloud.empty() || !(radius > 0.0)) return keep;
  const CellGrid grid = buildGrid(cloud, radius);
  const float radius_sq = float(radius * radius);  // as PCL/FLANN: within, squared in float
  const int needed = std::max(0, min_neighbors);
  auto countNeighbours = [&](size_t i) {
    const PointT& p = cloud.points[i];
    const Eigen::Vector3i& c = grid.cell_of[i];
    int found = 0;
    // Own cell first: in a downsampled scan it usually holds enough neighbours already.
    for (int step = 0; step < 27; ++step) {
      const int k = (step + 13) % 27;  // 13 = the centre cell (0, 0, 0)
      const auto cell =
          grid.cells.find(packCell(int64_t(c.x()) + k % 3 - 1, int64_t(c.y()) + (k / 3) % 3 - 1,
                                   int64_t(c.z()) + k / 9 - 1));
      if (cell == grid.cells.end()) continue;
      for (uint32_t j = cell->second.first; j < cell->second.second; ++j) {
        const uint32_t q = grid.order[j];
        if (q == i || !(squaredDistance(p, cloud.points[q]) <= radius_sq)) continue;
        if (++found >= needed) return true;
      }
    }
    return found >= needed;
  };
  auto run = [&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cloud.size(), 1024),
                      [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t i = r.begin(); i != r.end(); ++i) keep[i] = countNeighbours(i);
                      });
  };
  if (num_threads > 0) {
    tbb::task_arena arena(num_threads);
    arena.execute(run);
  } else {
    run();
  }
  return keep;
}

PointCloudPtr radiusOutlierRemovalGrid(const PointCloud& cloud, double radius, int min_neighbors,
                                       int num_threads) {
  const std::vector<uint8_t> keep = radiusInlierMask(cloud, radius, min_neighbors, num_threads);
  PointCloudPtr out = std::make_shared<PointCloud>();
  out->header = cloud.header;
  out->reserve(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i)
    if (keep[i]) out->push_back(cloud.points[i]);
  out->is_dense = true;
  return out;
}

}  // namespace osm_graph_slam
