#pragma once
// A drive along a simulated street with known truth for back-end tests: buildings, true poses,
// keyframe clouds (simulated LiDAR) and their wall segments from the production extractors.
#include <optional>
#include <random>
#include <vector>

#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/sim/wall_scan_simulator.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam::test {

inline Building toBuilding(int64_t id, const Polygon2& outline) {
  Building b;
  b.id = id;
  b.outline_enu = outline;
  size_t ref = 0;
  for (size_t i = 1; i < outline.size(); ++i)
    if (outline[i].x() < outline[ref].x()) ref = i;
  b.reference_pose = Pose2(outline[ref].x(), outline[ref].y(), 0.0);
  b.segments = polygonSegments(outline);
  return b;
}

/// A drive along a street with known truth. Keyframe segments come from simulated scans through
/// the production wall-point and segment extractors.
struct StreetDrive {
  std::vector<SimBuilding> scene;
  std::vector<Building> truth;
  std::vector<Pose2> true_poses;
  std::vector<std::vector<LineSegment2>> segments;
  std::vector<PointCloudPtr> clouds;  ///< sensor frame (kept only when asked for)

  explicit StreetDrive(int keyframes, double spacing = 2.5, bool keep_clouds = false)
      : StreetDrive(makeStreetScene(16, 11), keyframes, spacing, keep_clouds) {}

  StreetDrive(std::vector<SimBuilding> buildings, int keyframes, double spacing, bool keep_clouds)
      : scene(std::move(buildings)) {
    WallScanParams scan;
    scan.beams_per_ring = 900;
    const WallPointExtractor walls;
    const LineSegmentExtractor lines;
    for (int k = 0; k < keyframes; ++k) {
      // Gentle weave so that headings vary (otherwise every wall is parallel or orthogonal).
      const double x = -45.0 + spacing * k;
      const Pose2 pose(x, 0.8 * std::sin(0.05 * x), 0.04 * std::cos(0.05 * x));
      true_poses.push_back(pose);
      scan.seed = static_cast<uint32_t>(k + 1);
      const PointCloudPtr cloud = simulateWallScan(scene, pose, scan);
      segments.push_back(lines.extract(*walls.extract(*cloud)));
      if (keep_clouds) clouds.push_back(cloud);
    }
    // The map origin is the first position (the first GPS fix), as in the back-end.
    const Pose2 shift(-true_poses[0].x, -true_poses[0].y, 0.0);
    for (auto& p : true_poses) p = shift * p;
    for (size_t i = 0; i < scene.size(); ++i) {
      truth.push_back(
          toBuilding(static_cast<int64_t>(1000 + i), transformPolygon(scene[i].outline, shift)));
    }
  }

  /// Odometry with a yaw bias and a scale error per step (drift), starting at the truth.
  std::vector<Eigen::Isometry3d> odometry(double yaw_bias_per_step, double scale) const {
    std::vector<Eigen::Isometry3d> odom = {isometryFromPlanar(true_poses[0])};
    for (size_t k = 1; k < true_poses.size(); ++k) {
      Pose2 step = true_poses[k - 1].inverse() * true_poses[k];
      step = Pose2(step.x * scale, step.y * scale, step.theta + yaw_bias_per_step);
      odom.push_back(odom.back() * isometryFromPlanar(step));
    }
    return odom;
  }

  /// Buildings moved: each by its own random offset (sigma) plus a common shift.
  std::vector<Building> perturbedPrior(double sigma_xy, double sigma_theta, const Pose2& common,
                                       uint32_t seed) const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    std::vector<Building> out;
    for (const auto& b : truth) {
      const Pose2 about = b.reference_pose;
      const Pose2 own(sigma_xy * n(rng), sigma_xy * n(rng), sigma_theta * n(rng));
      const Pose2 move = common * about * own * about.inverse();
      out.push_back(toBuilding(b.id, transformPolygon(b.outline_enu, move)));
    }
    return out;
  }

  Trajectory trueTrajectory() const {
    Trajectory t;
    for (size_t k = 0; k < true_poses.size(); ++k)
      t.push_back({0.1 * k, isometryFromPlanar(true_poses[k])});
    return t;
  }

  /// Keyframes from `first` on with segments (and clouds when kept), then the buildings.
  /// gravity: every keyframe gets this IMU roll/pitch when given; gnss: the true positions.
  void feed(GraphBackend& backend, const std::vector<Eigen::Isometry3d>& odom,
            const std::vector<Building>& prior,
            const std::optional<Eigen::Vector2d>& gravity = std::nullopt, size_t first = 0,
            bool gnss = false) const {
    backend.addBuildings(prior, Eigen::Vector2d::Zero(), 1000.0);
    for (size_t k = first; k < odom.size(); ++k) {
      KeyframeInput kf = keyframe(k, odom);
      kf.gravity_roll_pitch = gravity;
      if (gnss) kf.gnss_position = true_poses[k].translation();
      backend.addKeyframe(kf);
      backend.addLineSegments(k, segments[k]);
    }
  }

  /// Keyframe k (its odometry pose, fitness and cloud when kept), without aiding.
  KeyframeInput keyframe(size_t k, const std::vector<Eigen::Isometry3d>& odom) const {
    KeyframeInput kf;
    kf.id = k;
    kf.stamp = 0.1 * k;
    kf.odom_pose = odom[k];
    kf.odom_fitness = 0.05;
    if (k < clouds.size()) kf.cloud = clouds[k];
    return kf;
  }
};

}  // namespace osm_graph_slam::test
