#include "osm_graph_slam/cloud/floor_detector.h"

#include <pcl/features/normal_3d.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_plane.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace osm_graph_slam {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

/// Least-squares plane (PCA) through the given points; normal oriented up. rms of the distances.
bool fitPlane(const PointCloud& cloud, const std::vector<int>& indices, Eigen::Vector4d* coeffs,
              double* rms) {
  if (indices.size() < 3) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i : indices) mean += cloud.points[i].getVector3fMap().cast<double>();
  mean /= double(indices.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int i : indices) {
    const Eigen::Vector3d d = cloud.points[i].getVector3fMap().cast<double>() - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  if (eig.info() != Eigen::Success) return false;
  Eigen::Vector3d n = eig.eigenvectors().col(0);  // smallest eigenvalue
  if (n.z() < 0.0) n = -n;
  *coeffs << n, -n.dot(mean);
  *rms = std::sqrt(std::max(0.0, eig.eigenvalues()(0)) / double(indices.size()));
  return true;
}

}  // namespace

std::string FloorHealth::update(uint64_t keyframe, const FloorDetection& detection) {
  if (detection.found) {
    ++found_;
    const bool was_lost = run_ >= warn_after_;
    const int run = run_;
    run_ = 0;
    if (was_lost)
      return "floor found again at keyframe " + std::to_string(keyframe) + " after " +
             std::to_string(run) + " keyframes without one";
    return {};
  }
  ++missing_;
  if (++run_ != warn_after_) return {};
  ++warnings_;
  return "no floor on " + std::to_string(run_) + " keyframes in a row (keyframe " +
         std::to_string(keyframe) + ": " + detection.reason +
         "); no plane constraints until one is found";
}

double floorTilt(const Eigen::Vector4d& coeffs) {
  const Eigen::Vector3d n = coeffs.head<3>().normalized();
  return std::acos(std::clamp(std::abs(n.z()), 0.0, 1.0));
}

FloorDetection FloorDetector::detect(const PointCloud& cloud) const {
  const FloorDetectorParams& p = params_;
  FloorDetection out;
  if (!p.enabled) {
    out.reason = "floor detection disabled";
    return out;
  }
  // 1. Clip: a height band around the expected floor, a ring around the vehicle.
  PointCloudPtr band = std::make_shared<PointCloud>();
  band->reserve(cloud.size() / 4);
  const double r2_min = p.min_range * p.min_range, r2_max = p.max_range * p.max_range;
  for (const PointT& pt : cloud.points) {
    if (!std::isfinite(pt.x) || !std::isfinite(pt.y) || !std::isfinite(pt.z)) continue;
    const double r2 = double(pt.x) * pt.x + double(pt.y) * pt.y;
    if (r2 < r2_min || r2 > r2_max || std::abs(pt.z - p.floor_z) > p.floor_z_tolerance) continue;
    band->push_back(pt);
  }
  if (band->size() < size_t(std::max(3, p.normal_neighbours))) {
    out.reason = "only " + std::to_string(band->size()) + " points in the floor band";
    return out;
  }
  // 2. Keep points with a near-vertical normal.
  pcl::NormalEstimation<PointT, pcl::Normal> ne;
  pcl::search::KdTree<PointT>::Ptr tree(new pcl::search::KdTree<PointT>);
  ne.setInputCloud(band);
  ne.setSearchMethod(tree);
  ne.setKSearch(p.normal_neighbours);
  ne.setViewPoint(0.0f, 0.0f, 0.0f);
  pcl::PointCloud<pcl::Normal> normals;
  ne.compute(normals);
  const double min_cos = std::cos(p.max_normal_tilt_deg * kDegToRad);
  PointCloudPtr candidates = std::make_shared<PointCloud>();
  candidates->reserve(band->size());
  for (size_t i = 0; i < band->size(); ++i) {
    const pcl::Normal& n = normals.points[i];
    if (std::isfinite(n.normal_z) && std::abs(n.normal_z) >= min_cos)
      candidates->push_back(band->points[i]);
  }
  out.candidates = candidates->size();
  if (candidates->size() < 3) {
    out.reason = "no point with a near-vertical normal among " + std::to_string(band->size());
    return out;
  }
  // 3. RANSAC plane, refined by least squares on its inliers.
  std::vector<int> inliers;
  if (int(candidates->size()) >= p.min_inliers) {
    pcl::SampleConsensusModelPlane<PointT>::Ptr model(
        new pcl::SampleConsensusModelPlane<PointT>(candidates));
    pcl::RandomSampleConsensus<PointT> ransac(model, p.ransac_distance);
    ransac.setMaxIterations(p.ransac_iterations);
    if (ransac.computeModel()) ransac.getInliers(inliers);
  }
  Eigen::Vector4d coeffs;
  double rms = 0.0;
  if (int(inliers.size()) >= p.min_inliers && fitPlane(*candidates, inliers, &coeffs, &rms)) {
    out.method = "ransac";
  } else {
    // 4. Rough terrain: no plane with enough support; fit the nearest points.
    const size_t ransac_support = inliers.size();
    inliers.clear();
    const double r2 = p.rough_radius * p.rough_radius;
    for (size_t i = 0; i < candidates->size(); ++i) {
      const PointT& pt = candidates->points[i];
      if (double(pt.x) * pt.x + double(pt.y) * pt.y <= r2) inliers.push_back(int(i));
    }
    if (p.rough_radius <= 0.0 || int(inliers.size()) < p.rough_min_points ||
        !fitPlane(*candidates, inliers, &coeffs, &rms) || rms > p.rough_max_rms) {
      out.reason = "no plane: RANSAC support " + std::to_string(ransac_support) + " < " +
                   std::to_string(p.min_inliers) + ", " + std::to_string(inliers.size()) +
                   " points within " + std::to_string(p.rough_radius) + " m" +
                   (inliers.size() >= 3 ? " (least-squares rms " + std::to_string(rms) + " m)"
                                        : std::string());
      return out;
    }
    out.method = "least_squares";
  }
  out.inliers = inliers.size();
  out.rms = rms;
  if (floorTilt(coeffs) > p.max_floor_tilt_deg * kDegToRad) {
    out.reason = "plane tilted " + std::to_string(floorTilt(coeffs) / kDegToRad) + " deg";
    return out;
  }
  out.coeffs = coeffs;
  out.found = true;
  return out;
}

}  // namespace osm_graph_slam
