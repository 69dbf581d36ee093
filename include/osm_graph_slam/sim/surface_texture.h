#pragma once
// What a simulated LiDAR's intensity channel sees on a surface: its reflectance by class and by
// where on the surface the ray lands. Real returns carry texture (KITTI: bright lane markings and
// signs, dark glass and foliage gaps, asphalt patches) that an intensity cue registers on
// (MCS-SLAM, multi_cue/); a uniform reflectivity per surface gives that cue nothing to hold.
// Only the intensity uses it: which returns are detected (and so every point's geometry) still
// follows the surface's own reflectivity, so drives keep the geometry they had.
#include <Eigen/Core>

#include "osm_graph_slam/sim/world.h"

namespace osm_graph_slam::sim {

struct SurfaceTextureParams {
  bool enabled = true;               ///< false: the surface's uniform reflectivity
  double asphalt_cell = 0.5;         ///< [m] asphalt patches (each its own shade)
  double asphalt_variation = 0.35;   ///< +- this fraction of the ground reflectivity
  double marking_share = 0.03;       ///< of asphalt cells painted (markings, manhole covers)
  float marking_reflectance = 0.7f;  ///< retro-reflective paint
  double storey_height = 3.0;        ///< [m] facade rows
  double window_spacing = 2.4;       ///< [m] along the wall
  double window_fill = 0.55;         ///< share of a storey and of a bay that is glass
  float glass_reflectance = 0.05f;   ///< specular glass returns little to the sensor
  double foliage_cell = 0.3;         ///< [m] leaf clumps and gaps
};

/// The reflectance the intensity of a return from `hit` at world point `p` is computed with.
float surfaceReflectance(const World& world, const RayHit& hit, const Eigen::Vector3d& p,
                         const SurfaceTextureParams& params);

}  // namespace osm_graph_slam::sim
