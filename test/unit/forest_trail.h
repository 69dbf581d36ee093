#pragma once
// A simulated forest with trails and prefiltered HDL-64E clouds along them, for the landmark
// (GeoSLAM) tests: loop detection and global localisation by geometric hierarchies.
#include <Eigen/Geometry>
#include <utility>
#include <vector>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/sim/forest_world.h"
#include "osm_graph_slam/sim/lidar.h"

namespace osm_graph_slam::test {

/// A 220 m intermediate-density forest (thesis Table 4.4) with trails 110 m apart.
inline sim::Scene makeForest(uint64_t seed) {
  sim::ForestParams p;
  sim::forestPreset("intermediate", p);
  p.seed = seed;
  p.size = 220.0;
  p.trail_spacing = 110.0;
  sim::Scene scene = sim::forestScene(p);
  scene.world.finalize();
  return scene;
}

/// Point and heading `s` metres along a polyline.
inline std::pair<Eigen::Vector2d, double> along(const std::vector<Eigen::Vector2d>& line,
                                                double s) {
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d d = line[i + 1] - line[i];
    const double len = d.norm();
    if (s <= len || i + 2 == line.size()) {
      return {line[i] + d * std::min(1.0, s / len), std::atan2(d.y(), d.x())};
    }
    s -= len;
  }
  return {line.front(), 0.0};
}

/// The sensor 1.73 m above the ground at xy, heading yaw.
inline Eigen::Isometry3d sensorPose(const sim::Scene& scene, const Eigen::Vector2d& xy,
                                    double yaw) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.rotate(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  pose.translation() =
      Eigen::Vector3d(xy.x(), xy.y(), scene.world.ground.height(xy.x(), xy.y()) + 1.73);
  return pose;
}

/// A prefiltered HDL-64E scan (sensor frame) from pose.
inline PointCloudConstPtr keyframeCloud(const sim::Scene& scene, const Eigen::Isometry3d& pose,
                                        uint64_t seed) {
  const PointCloud raw =
      sim::simulateScan(
          scene.world, sim::LidarModel::hdl64e(), [pose](double) { return pose; }, 0.0, seed, 0)
          .cloud;
  return CloudPrefilter().filter(raw).cloud;
}

}  // namespace osm_graph_slam::test
