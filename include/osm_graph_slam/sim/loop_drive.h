#pragma once
// A simulated drive for loop detection (loop_benchmark --candidates, loop tests): keyframes every
// `spacing` metres of an UrbanSimulator route (procedural city or forest world), each cloud
// ray-cast by the HDL-64E model and prefiltered like the pipeline's keyframes (CloudPrefilter
// defaults, sensor frame), with odometry that drifts (scale error + heading bias per metre).
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/loop/loop_detector.h"

namespace osm_graph_slam::sim {

struct LoopDriveParams {
  std::string world = "forest";                 ///< city | forest | park
  std::string forest_density = "intermediate";  ///< sparse | intermediate | dense
  uint64_t seed = 1;
  double length = 500.0;                ///< [m] route (it returns to its start)
  double spacing = 4.0;                 ///< [m] between keyframes
  double odometry_scale_error = 0.005;  ///< travelled distance overestimated by this fraction
  double odometry_yaw_bias = 0.003 * M_PI / 180.0;  ///< [rad/m] heading drift
  int max_keyframes = 0;                            ///< 0: the whole route
};

struct LoopDrive {
  std::vector<Eigen::Isometry3d> truth;  ///< sensor poses in the world
  std::vector<LoopKeyframe> keyframes;   ///< prefiltered clouds, drifting odometry
  double simulate_s = 0.0;               ///< ray casting + prefiltering
};

/// False with a reason when the world or route cannot be built.
bool simulateLoopDrive(const LoopDriveParams& params, LoopDrive& drive, std::string* error);

}  // namespace osm_graph_slam::sim
