#include "osm_graph_slam/cloud/cloud_prefilter.h"

#include <pcl/common/transforms.h>
#include <pcl/filters/radius_outlier_removal.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "osm_graph_slam/cloud/radius_outlier_grid.h"
#include "osm_graph_slam/cloud/voxel_filter.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

double elapsedMs(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

bool isFinitePoint(const PointT& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

PointCloudPtr emptyLike(const PointCloud& header_source) {
  PointCloudPtr cloud = std::make_shared<PointCloud>();
  cloud->header = header_source.header;
  cloud->is_dense = true;
  return cloud;
}

float medianOf(std::vector<float> values) {
  if (values.empty()) return 0.0f;
  auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

/// One octant: its own points first (filtered), then support points of neighbouring octants
/// that lie within the margin of its borders (only used as neighbours).
struct Octant {
  PointCloudPtr cloud = std::make_shared<PointCloud>();
  size_t core_size = 0;
};

}  // namespace

CloudPrefilter::CloudPrefilter(const CloudPrefilterParams& params) : params_(params) {
  if (params_.radius_backend != "grid" && params_.radius_backend != "pcl")
    throw std::invalid_argument("CloudPrefilter: radius_backend '" + params_.radius_backend +
                                "' (grid | pcl)");
}

void CloudPrefilter::setSensorToBase(const Eigen::Isometry3d& sensor_to_base) {
  params_.sensor_to_base = sensor_to_base;
}

CloudPrefilterResult CloudPrefilter::filter(const PointCloud& input) const {
  const auto start = Clock::now();
  CloudPrefilterResult result;
  result.stats.input_points = input.size();
  result.cloud = emptyLike(input);
  if (input.empty()) {
    result.reason = "input cloud is empty";
    return result;
  }

  // Invalid-point removal and range crop in one pass (both are per-point tests).
  PointCloudPtr kept = emptyLike(input);
  kept->reserve(input.size());
  const double min_sq = params_.min_range * params_.min_range;
  const double max_sq = params_.max_range * params_.max_range;
  size_t finite = 0;
  for (const auto& p : input.points) {
    const bool valid = isFinitePoint(p);
    if (!valid && params_.remove_invalid) continue;
    if (valid) ++finite;
    if (params_.use_range_crop) {
      const double d_sq = double(p.x) * p.x + double(p.y) * p.y + double(p.z) * p.z;
      if (!(d_sq >= min_sq && d_sq <= max_sq)) continue;
    }
    kept->push_back(p);
  }
  kept->header = input.header;
  kept->is_dense = params_.remove_invalid || finite == kept->size();
  result.stats.after_invalid = params_.remove_invalid ? finite : input.size();
  result.stats.after_crop = kept->size();
  if (finite == 0) {
    result.reason = "all " + std::to_string(input.size()) + " points are NaN/Inf";
    return result;
  }
  if (kept->empty()) {
    result.reason = "no point within the range crop [" + std::to_string(params_.min_range) + ", " +
                    std::to_string(params_.max_range) + "] m";
    return result;
  }
  if (!params_.sensor_to_base.matrix().isIdentity(1e-12)) {
    pcl::transformPointCloud(*kept, *kept, params_.sensor_to_base.matrix().cast<float>());
  }
  result.stats.time_invalid_crop_ms = elapsedMs(start);

  PointCloudPtr current = kept;
  if (params_.use_voxel_grid && params_.voxel_leaf_size > 0.0) {
    const auto t = Clock::now();
    current = voxelize(current);
    result.stats.time_voxel_ms = elapsedMs(t);
  }
  result.stats.after_voxel = current->size();

  if (params_.use_outlier_removal) {
    const auto t = Clock::now();
    current = removeOutliers(current, params_.parallel_octants);
    result.stats.time_outlier_ms = elapsedMs(t);
  }
  current->header = input.header;
  result.stats.output_points = current->size();
  result.stats.time_total_ms = elapsedMs(start);
  result.cloud = current;
  if (current->empty()) {
    result.reason = "outlier removal left no point";
    return result;
  }
  result.ok = true;
  return result;
}

PointCloudPtr CloudPrefilter::voxelize(const PointCloudConstPtr& cloud) const {
  return voxelDownsample(cloud, params_.voxel_leaf_size, params_.voxel_method == "exact");
}

PointCloudPtr CloudPrefilter::removeOutliers(const PointCloudConstPtr& cloud,
                                             bool parallel_octants) const {
  if (!cloud || cloud->empty()) return cloud ? emptyLike(*cloud) : std::make_shared<PointCloud>();
  if (params_.outlier_method != "statistical" && params_.radius_backend == "grid")
    return removeOutliersGrid(cloud, parallel_octants);
  return parallel_octants ? removeOutliersOctants(cloud) : removeOutliersWhole(cloud);
}

namespace {

/// Filters the first core_size points of cloud (the rest only serve as neighbours).
void filterCore(const CloudPrefilterParams& params, const PointCloudConstPtr& cloud,
                size_t core_size, PointCloud& out) {
  pcl::IndicesPtr core(new pcl::Indices(core_size));
  for (size_t i = 0; i < core_size; ++i) (*core)[i] = static_cast<pcl::index_t>(i);
  if (params.outlier_method == "statistical") {
    pcl::StatisticalOutlierRemoval<PointT> sor;
    sor.setMeanK(params.statistical_mean_k);
    sor.setStddevMulThresh(params.statistical_stddev);
    sor.setInputCloud(cloud);
    sor.setIndices(core);
    sor.filter(out);
  } else {
    pcl::RadiusOutlierRemoval<PointT> ror;
    ror.setRadiusSearch(params.radius_search);
    ror.setMinNeighborsInRadius(params.radius_min_neighbors);
    ror.setInputCloud(cloud);
    ror.setIndices(core);
    ror.filter(out);
  }
}

}  // namespace

PointCloudPtr CloudPrefilter::removeOutliersWhole(const PointCloudConstPtr& cloud) const {
  PointCloudPtr out = std::make_shared<PointCloud>();
  filterCore(params_, cloud, cloud->size(), *out);
  out->header = cloud->header;
  return out;
}

namespace {

/// The octants' common corner: the per-axis medians, so that the octants carry similar loads.
Eigen::Vector3f octantCenter(const PointCloud& cloud) {
  std::array<std::vector<float>, 3> coords;
  for (auto& c : coords) c.reserve(cloud.size());
  for (const auto& p : cloud.points) {
    coords[0].push_back(p.x);
    coords[1].push_back(p.y);
    coords[2].push_back(p.z);
  }
  return Eigen::Vector3f(medianOf(std::move(coords[0])), medianOf(std::move(coords[1])),
                         medianOf(std::move(coords[2])));
}

int octantOf(const PointT& p, const Eigen::Vector3f& center) {
  const Eigen::Vector3f d = p.getVector3fMap() - center;
  return (d.x() >= 0.0f ? 1 : 0) | (d.y() >= 0.0f ? 2 : 0) | (d.z() >= 0.0f ? 4 : 0);
}

}  // namespace

PointCloudPtr CloudPrefilter::removeOutliersGrid(const PointCloudConstPtr& cloud,
                                                 bool octant_order) const {
  const std::vector<uint8_t> keep = radiusInlierMask(
      *cloud, params_.radius_search, params_.radius_min_neighbors, params_.num_threads);
  PointCloudPtr out = std::make_shared<PointCloud>();
  out->header = cloud->header;
  out->is_dense = true;
  out->reserve(cloud->size());
  if (!octant_order) {
    for (size_t i = 0; i < cloud->size(); ++i)
      if (keep[i]) out->push_back(cloud->points[i]);
    return out;
  }
  // The order the octant-parallel PCL filter gives (octant by octant, input order inside), so
  // that switching the backend changes nothing downstream: the keyframe clouds' point order
  // steers the RANSAC samples of walls and floors.
  const Eigen::Vector3f center = octantCenter(*cloud);
  std::vector<uint8_t> home(cloud->size());
  for (size_t i = 0; i < cloud->size(); ++i) home[i] = uint8_t(octantOf(cloud->points[i], center));
  for (uint8_t o = 0; o < 8; ++o)
    for (size_t i = 0; i < cloud->size(); ++i)
      if (keep[i] && home[i] == o) out->push_back(cloud->points[i]);
  return out;
}

PointCloudPtr CloudPrefilter::removeOutliersOctants(const PointCloudConstPtr& cloud) const {
  const Eigen::Vector3f center = octantCenter(*cloud);
  double margin = params_.octant_margin;
  if (margin <= 0.0) margin = params_.outlier_method == "statistical" ? 2.0 : params_.radius_search;

  std::array<Octant, 8> octants;
  std::array<std::vector<size_t>, 8> support;
  for (size_t i = 0; i < cloud->size(); ++i) {
    const auto& p = cloud->points[i];
    const Eigen::Vector3f d = p.getVector3fMap() - center;
    int home = 0;
    int near_mask = 0;
    for (int axis = 0; axis < 3; ++axis) {
      if (d[axis] >= 0.0f) home |= 1 << axis;
      if (std::abs(d[axis]) < margin) near_mask |= 1 << axis;
    }
    octants[home].cloud->push_back(p);
    // Every other octant reachable by flipping only axes near the border gets p as support.
    for (int flip = near_mask; flip != 0; flip = (flip - 1) & near_mask) {
      support[home ^ flip].push_back(i);
    }
  }
  for (int o = 0; o < 8; ++o) {
    octants[o].core_size = octants[o].cloud->size();
    for (size_t i : support[o]) octants[o].cloud->push_back(cloud->points[i]);
  }

  std::array<PointCloud, 8> filtered;
  auto run = [&] {
    tbb::parallel_for(0, 8, [&](int o) {
      if (octants[o].core_size > 0)
        filterCore(params_, octants[o].cloud, octants[o].core_size, filtered[o]);
    });
  };
  if (params_.num_threads > 0) {
    tbb::task_arena arena(params_.num_threads);
    arena.execute(run);
  } else {
    run();
  }
  PointCloudPtr out = std::make_shared<PointCloud>();
  for (const auto& part : filtered) *out += part;
  out->header = cloud->header;
  out->is_dense = true;
  return out;
}

}  // namespace osm_graph_slam
