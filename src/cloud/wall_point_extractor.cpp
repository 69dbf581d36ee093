#include "osm_graph_slam/cloud/wall_point_extractor.h"

#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/search/kdtree.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <chrono>
#include <cmath>
#include <nanoflann.hpp>
#include <thread>
#include <vector>

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// nanoflann view of a PCL cloud (no copy).
struct CloudAdaptor {
  const PointCloud& cloud;
  size_t kdtree_get_point_count() const { return cloud.size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return cloud[i].data[dim]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};
using KdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>,
                                        CloudAdaptor, 3, uint32_t>;

/// Step 1: finite points above the horizon, within the range limits.
PointCloudPtr cutBelowHorizon(const PointCloud& in, const WallPointExtractorParams& p,
                              WallPointStats& stats) {
  auto out = std::make_shared<PointCloud>();
  out->reserve(in.size() / 3);
  const double min_r2 = p.min_range * p.min_range;
  const double max_r2 = p.max_range > 0.0 ? p.max_range * p.max_range : HUGE_VAL;
  for (const auto& pt : in) {
    if (!std::isfinite(pt.x) || !std::isfinite(pt.y) || !std::isfinite(pt.z)) continue;
    ++stats.finite;
    if (pt.z < p.horizon_height) continue;
    const double r2 = double(pt.x) * pt.x + double(pt.y) * pt.y;
    if (r2 < min_r2 || r2 > max_r2) continue;
    out->push_back(pt);
  }
  out->width = out->size();
  out->height = 1;
  out->is_dense = true;
  return out;
}

PointCloudPtr voxelize(const PointCloudPtr& in, double leaf) {
  if (leaf <= 0.0 || in->empty()) return in;
  pcl::VoxelGrid<PointT> grid;
  grid.setLeafSize(leaf, leaf, leaf);
  grid.setInputCloud(in);
  auto out = std::make_shared<PointCloud>();
  grid.filter(*out);
  return out;
}

/// Vertical-surface test of one neighbourhood given its covariance. A linear neighbourhood (one
/// scan ring) has no defined plane; it lies in a vertical plane exactly when it is horizontal.
bool isVerticalSurface(const Eigen::Matrix3f& cov, float max_sin) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> es;
  es.computeDirect(cov);
  const Eigen::Vector3f ev = es.eigenvalues();  // ascending
  if (!(ev(2) > 0.0f)) return false;
  const bool linear = ev(1) < 0.05f * ev(2);
  if (linear) return std::abs(es.eigenvectors().col(2).z()) < max_sin;
  return std::abs(es.eigenvectors().col(0).z()) < max_sin;
}

/// Step 2 (ours): nanoflann kNN + closed-form 3x3 eigen decomposition, TBB over points.
std::vector<char> verticalMaskNanoflann(const PointCloud& cloud,
                                        const WallPointExtractorParams& p) {
  std::vector<char> keep(cloud.size(), 0);
  CloudAdaptor adaptor{cloud};
  KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  const size_t k = std::max(3, p.k_neighbors);
  const float max_sin = std::sin(p.max_normal_angle_deg * M_PI / 180.0);
  const float max_d2 = p.max_neighbor_distance * p.max_neighbor_distance;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cloud.size(), 256),
                    [&](const tbb::blocked_range<size_t>& range) {
                      std::vector<uint32_t> idx(k);
                      std::vector<float> d2(k);
                      for (size_t i = range.begin(); i != range.end(); ++i) {
                        const size_t n = tree.knnSearch(cloud[i].data, k, idx.data(), d2.data());
                        if (n < 3 || d2[n - 1] > max_d2) continue;
                        Eigen::Vector3f mean = Eigen::Vector3f::Zero();
                        for (size_t j = 0; j < n; ++j) mean += cloud[idx[j]].getVector3fMap();
                        mean /= float(n);
                        Eigen::Matrix3f cov = Eigen::Matrix3f::Zero();
                        for (size_t j = 0; j < n; ++j) {
                          const Eigen::Vector3f d = cloud[idx[j]].getVector3fMap() - mean;
                          cov.noalias() += d * d.transpose();
                        }
                        keep[i] = isVerticalSurface(cov, max_sin);
                      }
                    });
  return keep;
}

/// Step 2 (library baseline): pcl::NormalEstimationOMP with a FLANN kd-tree.
std::vector<char> verticalMaskPcl(const PointCloudPtr& cloud, const WallPointExtractorParams& p) {
  pcl::NormalEstimationOMP<PointT, pcl::Normal> ne(p.num_threads > 0 ? p.num_threads : 0);
  ne.setInputCloud(cloud);
  ne.setSearchMethod(std::make_shared<pcl::search::KdTree<PointT>>());
  ne.setKSearch(std::max(3, p.k_neighbors));
  pcl::PointCloud<pcl::Normal> normals;
  ne.compute(normals);
  const float max_sin = std::sin(p.max_normal_angle_deg * M_PI / 180.0);
  std::vector<char> keep(cloud->size(), 0);
  for (size_t i = 0; i < normals.size(); ++i) {
    const float nz = normals[i].normal_z;
    keep[i] = std::isfinite(nz) && std::abs(nz) < max_sin;
  }
  return keep;
}

}  // namespace

WallPointExtractor::WallPointExtractor(const WallPointExtractorParams& params,
                                       std::shared_ptr<const Logger> logger)
    : params_(params), logger_(logger ? std::move(logger) : std::make_shared<Logger>()) {
  if (params_.normal_backend != "nanoflann" && params_.normal_backend != "pcl") {
    logger_->warn("WallPointExtractor: unknown normal_backend '" + params_.normal_backend +
                  "', using nanoflann");
    params_.normal_backend = "nanoflann";
  }
}

PointCloudPtr WallPointExtractor::extract(const PointCloud& cloud,
                                          WallPointStats* stats_out) const {
  const auto t0 = Clock::now();
  WallPointStats stats;
  stats.input = cloud.size();
  auto since = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };
  PointCloudPtr above = cutBelowHorizon(cloud, params_, stats);
  stats.cut_ms = since(t0);
  if (stats.finite < stats.input) {
    logger_->warnOnce("wall_nan", "WallPointExtractor: dropping non-finite points (first seen: " +
                                      std::to_string(stats.input - stats.finite) + " of " +
                                      std::to_string(stats.input) + ")");
  }
  stats.above_horizon = above->size();
  const auto t1 = Clock::now();
  PointCloudPtr sparse = voxelize(above, params_.voxel_size);
  stats.voxelized = sparse->size();
  stats.voxel_ms = since(t1);
  const auto t2 = Clock::now();

  auto walls = std::make_shared<PointCloud>();
  if (sparse->size() >= 3) {
    std::vector<char> keep;
    const int threads =
        params_.num_threads > 0 ? params_.num_threads : int(std::thread::hardware_concurrency());
    if (params_.normal_backend == "pcl") {
      keep = verticalMaskPcl(sparse, params_);
    } else {
      tbb::task_arena arena(std::max(1, threads));
      arena.execute([&] { keep = verticalMaskNanoflann(*sparse, params_); });
    }
    walls->reserve(sparse->size());
    for (size_t i = 0; i < sparse->size(); ++i) {
      if (!keep[i]) continue;
      PointT pt = (*sparse)[i];
      pt.z = 0.0f;  // step 3: flatten last, the plane test needed z
      walls->push_back(pt);
    }
  }
  stats.normal_ms = since(t2);
  walls->width = walls->size();
  walls->height = 1;
  walls->is_dense = true;
  walls->header = cloud.header;
  stats.walls = walls->size();
  stats.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (stats_out) *stats_out = stats;
  return walls;
}

}  // namespace osm_graph_slam
