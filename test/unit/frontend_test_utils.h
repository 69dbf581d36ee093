#pragma once
// Helpers shared by the front-end unit tests: real scans, ground truth, synthetic scenes, errors.
#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"

namespace osm_graph_slam::test {

/// A tracker result as TrackingHealth sees it (a failed match carries a reason).
inline TrackResult trackResult(TrackStatus status, bool new_keyframe, uint64_t keyframe_id = 0) {
  TrackResult r;
  r.status = status;
  r.new_keyframe = new_keyframe;
  r.keyframe_id = keyframe_id;
  r.reanchored = status == TrackStatus::kReanchored;
  if (status == TrackStatus::kMatchFailed) r.message = "fitness 3.2 above max_fitness 1";
  return r;
}

inline PointCloudPtr loadScan(const std::string& path) {
  PointCloudPtr cloud = std::make_shared<PointCloud>();
  std::string error;
  if (!readKittiBin(path, *cloud, &error)) ADD_FAILURE() << error;
  return cloud;
}

inline PointCloudPtr loadFilteredScan(const std::string& path,
                                      const CloudPrefilterParams& params = {}) {
  const auto raw = loadScan(path);
  return CloudPrefilter(params).filter(*raw).cloud;
}

/// Reads the 94 -> 95 relative motion (points of scan b in scan a's frame) from
/// gt_relative_lidar.txt: "a b r00 r01 r02 t0 r10 ... t2".
inline Eigen::Isometry3d readGroundTruthRelative(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    int a = 0, b = 0;
    row >> a >> b;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) row >> m(r, c);
    Eigen::Isometry3d t(m);
    return t;
  }
  ADD_FAILURE() << "no ground truth row in " << path;
  return Eigen::Isometry3d::Identity();
}

inline double translationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}

inline double rotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd((a.inverse() * b).linear()).angle() * 180.0 / M_PI;
}

/// A street-like synthetic scene: ground, building facades at several headings, poles and boxes,
/// so every degree of freedom is constrained.
inline PointCloudPtr syntheticScene(int points_per_surface = 1500, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloudPtr cloud = std::make_shared<PointCloud>();
  auto add = [&](const Eigen::Vector3f& p) {
    PointT q;
    q.getVector3fMap() = p;
    q.intensity = 1.0f;
    cloud->push_back(q);
  };
  for (int i = 0; i < points_per_surface * 2; ++i) add({25 * u(rng), 25 * u(rng), -1.7f});
  const float headings[] = {0.0f, 0.5f, 1.57f, 2.3f};
  const float offsets[] = {12.0f, -14.0f, 10.0f, -9.0f};
  for (int w = 0; w < 4; ++w) {
    const Eigen::Vector3f dir(std::cos(headings[w]), std::sin(headings[w]), 0.0f);
    const Eigen::Vector3f normal(-dir.y(), dir.x(), 0.0f);
    for (int i = 0; i < points_per_surface; ++i) {
      add(normal * offsets[w] + dir * (20 * u(rng)) + Eigen::Vector3f(0, 0, 2.5f + 4.0f * u(rng)));
    }
  }
  for (int pole = 0; pole < 6; ++pole) {
    const Eigen::Vector2f c(-15.0f + 6.0f * pole, pole % 2 ? 5.0f : -6.0f);
    for (int i = 0; i < points_per_surface / 4; ++i) {
      const float a = static_cast<float>(M_PI) * u(rng);
      add({c.x() + 0.3f * std::cos(a), c.y() + 0.3f * std::sin(a), 1.0f + 2.5f * u(rng)});
    }
  }
  cloud->width = cloud->size();
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

inline PointCloudPtr transformed(const PointCloud& cloud, const Eigen::Isometry3d& t) {
  PointCloudPtr out = std::make_shared<PointCloud>(cloud);
  for (auto& p : out->points)
    p.getVector3fMap() = (t * p.getVector3fMap().cast<double>()).cast<float>();
  return out;
}

}  // namespace osm_graph_slam::test
