#include "osm_graph_slam/cloud/map_cloud.h"

#include <pcl/common/transforms.h>

#include <cmath>
#include <unordered_map>

namespace osm_graph_slam {
namespace {

struct VoxelSum {
  double x = 0, y = 0, z = 0, intensity = 0;
  size_t n = 0;
};

int64_t voxelKey(const PointT& p, double inv) {
  // 21 bits per axis: ±1,048,576 voxels, i.e. ±105 km at 0.1 m.
  const auto q = [inv](float v) {
    return static_cast<int64_t>(std::floor(v * inv)) & ((int64_t{1} << 21) - 1);
  };
  return (q(p.x) << 42) | (q(p.y) << 21) | q(p.z);
}

}  // namespace

PointCloudPtr mergeClouds(const std::vector<PosedCloud>& clouds, double resolution) {
  auto map = std::make_shared<PointCloud>();
  PointCloud transformed;
  if (resolution <= 0.0) {
    for (const auto& posed : clouds) {
      const PointCloudConstPtr cloud = posed.cloud.load();
      if (!cloud) continue;
      pcl::transformPointCloud(*cloud, transformed, posed.pose.matrix().cast<float>());
      *map += transformed;
    }
    return map;
  }
  const double inv = 1.0 / resolution;
  std::unordered_map<int64_t, VoxelSum> voxels;
  for (const auto& posed : clouds) {
    const PointCloudConstPtr cloud = posed.cloud.load();
    if (!cloud) continue;
    pcl::transformPointCloud(*cloud, transformed, posed.pose.matrix().cast<float>());
    for (const auto& p : transformed) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
      VoxelSum& v = voxels[voxelKey(p, inv)];
      v.x += p.x;
      v.y += p.y;
      v.z += p.z;
      v.intensity += p.intensity;
      ++v.n;
    }
  }
  map->reserve(voxels.size());
  for (const auto& [key, v] : voxels) {
    PointT p;
    const double n = static_cast<double>(v.n);
    p.x = static_cast<float>(v.x / n);
    p.y = static_cast<float>(v.y / n);
    p.z = static_cast<float>(v.z / n);
    p.intensity = static_cast<float>(v.intensity / n);
    map->push_back(p);
  }
  map->width = static_cast<uint32_t>(map->size());
  map->height = 1;
  map->is_dense = true;
  return map;
}

}  // namespace osm_graph_slam
