#include "osm_graph_slam/cloud/voxel_filter.h"

#include <pcl/filters/approximate_voxel_grid.h>
#include <pcl/filters/voxel_grid.h>

#include <boost/sort/spreadsort/integer_sort.hpp>
#include <cmath>
#include <cstdint>
#include <vector>

namespace osm_graph_slam {

PointCloudPtr voxelDownsample(const PointCloudConstPtr& cloud, double leaf, bool exact) {
  PointCloudPtr out = std::make_shared<PointCloud>();
  const float l = static_cast<float>(leaf);
  if (exact) {
    pcl::VoxelGrid<PointT> grid;
    grid.setLeafSize(l, l, l);
    grid.setInputCloud(cloud);
    grid.filter(*out);
  } else {
    pcl::ApproximateVoxelGrid<PointT> grid;
    grid.setLeafSize(l, l, l);
    grid.setInputCloud(cloud);
    grid.filter(*out);
  }
  out->header = cloud->header;
  return out;
}

namespace {

/// std::floor for floats well inside the int range, without the libm call (no SSE4.1 here).
int floorToInt(float v) {
  const int i = static_cast<int>(v);
  return v < static_cast<float>(i) ? i - 1 : i;
}

/// (z, y, x) voxel indices biased to be non-negative, z most significant: ascending keys are
/// pcl::VoxelGrid's order (x fastest, then y, then z).
constexpr int kBias = 1 << 20;
uint64_t voxelKey(int x, int y, int z) {
  return (uint64_t(z + kBias) << 42) | (uint64_t(y + kBias) << 21) | uint64_t(x + kBias);
}

size_t slotOf(uint64_t key, size_t mask) {
  return static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> 17) & mask;
}

}  // namespace

PointCloudPtr voxelCentroids(const PointCloud& cloud, double leaf) {
  auto out = std::make_shared<PointCloud>();
  // pcl::VoxelGrid's voxel of a point: floor(coordinate * (1 / float leaf)) in float.
  const float inv = 1.0f / static_cast<float>(leaf);
  const float limit = static_cast<float>(kBias - 1);
  const size_t n = cloud.size();
  // Open addressing, at most half full; sums per voxel in float in the cloud's order.
  size_t capacity = 16;
  while (capacity < 2 * n) capacity <<= 1;
  constexpr uint64_t kEmpty = ~uint64_t(0);
  std::vector<uint64_t> slot_key(capacity, kEmpty);
  std::vector<uint32_t> slot_voxel(capacity);
  struct Sum {
    float x = 0.f, y = 0.f, z = 0.f, intensity = 0.f;
    uint32_t count = 0;
  };
  std::vector<Sum> sums;
  std::vector<uint64_t> keys;
  for (const PointT& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const float fx = p.x * inv, fy = p.y * inv, fz = p.z * inv;
    if (!(std::abs(fx) < limit && std::abs(fy) < limit && std::abs(fz) < limit)) {
      // Beyond +-2^20 voxels: PCL's filter (which has limits of its own) on the finite points.
      auto finite = std::make_shared<PointCloud>();
      for (const auto& q : cloud.points)
        if (std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z)) finite->push_back(q);
      return voxelDownsample(finite, leaf, true);  // finite's header is empty, as promised
    }
    const uint64_t key = voxelKey(floorToInt(fx), floorToInt(fy), floorToInt(fz));
    size_t s = slotOf(key, capacity - 1);
    while (slot_key[s] != kEmpty && slot_key[s] != key) s = (s + 1) & (capacity - 1);
    if (slot_key[s] == kEmpty) {
      slot_key[s] = key;
      slot_voxel[s] = static_cast<uint32_t>(sums.size());
      sums.emplace_back();
      keys.push_back(key);
    }
    Sum& sum = sums[slot_voxel[s]];
    sum.x += p.x;
    sum.y += p.y;
    sum.z += p.z;
    sum.intensity += p.intensity;
    ++sum.count;
  }
  boost::sort::spreadsort::integer_sort(keys.begin(), keys.end());
  out->resize(keys.size());
  for (size_t o = 0; o < keys.size(); ++o) {
    size_t s = slotOf(keys[o], capacity - 1);
    while (slot_key[s] != keys[o]) s = (s + 1) & (capacity - 1);
    const Sum& sum = sums[slot_voxel[s]];
    const float count = static_cast<float>(sum.count);
    PointT& q = out->points[o];
    q.x = sum.x / count;
    q.y = sum.y / count;
    q.z = sum.z / count;
    q.intensity = sum.intensity / count;
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

}  // namespace osm_graph_slam
