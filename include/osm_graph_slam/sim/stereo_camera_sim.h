#pragma once
// A rectified stereo camera in the simulated world (D3VIL-SLAM's sensor, issue 56): each pixel of
// both images is a ray cast into the same scene the LiDAR sees, shaded by the surface's texture
// (sim/surface_texture.h: asphalt patches and markings, glass in the facades, foliage clumps) and
// its incidence, with a sky above, an exposure and sensor noise. KITTI's geometry by default.
// Deterministic: the noise of every pixel comes from a hash of (seed, frame, pixel).
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "osm_graph_slam/sim/surface_texture.h"
#include "osm_graph_slam/sim/world.h"
#include "osm_graph_slam/visual/stereo_camera.h"

namespace osm_graph_slam::sim {

struct StereoCameraModel {
  int width = 1226, height = 370;  ///< KITTI's rectified gray cameras
  double fx = 707.0912, fy = 707.0912, cx = 601.8873, cy = 183.1104;  ///< [px]
  double baseline = 0.537;   ///< [m] right camera to the right of the left one
  double max_range = 150.0;  ///< [m] farther: sky
  /// Shading: gray = exposure * 255 * reflectance * (ambient + (1 - ambient) * cos(incidence)).
  double exposure = 1.6;
  double ambient = 0.4;
  uint8_t sky = 200;         ///< gray level of the sky
  double noise_sigma = 2.0;  ///< [gray levels] sensor noise
  /// The facade and ground texture at camera scale: finer cells than the LiDAR needs.
  SurfaceTextureParams texture = [] {
    SurfaceTextureParams t;
    t.asphalt_cell = 0.25;
    t.foliage_cell = 0.15;
    return t;
  }();
  /// The calibration a stereo tracker of these images uses.
  StereoCamera camera() const {
    StereoCamera c;
    c.fx = fx;
    c.fy = fy;
    c.cx = cx;
    c.cy = cy;
    c.baseline = baseline;
    return c;
  }
};

/// Left camera (x right, y down, z forward) in the world, from the LiDAR's pose: KITTI's gray
/// camera sits 0.27 m ahead of and 0.08 m below the Velodyne, looking along its x axis.
Eigen::Isometry3d kittiCameraFromLidar(const Eigen::Isometry3d& world_from_lidar);

/// One gray image (CV_8UC1) seen from `world_from_camera` at time t (moving objects then).
cv::Mat renderCameraImage(const World& world, const StereoCameraModel& model,
                          const Eigen::Isometry3d& world_from_camera, double t, uint64_t seed);

/// Both images of the pair whose left camera is at `world_from_left`.
void renderStereoPair(const World& world, const StereoCameraModel& model,
                      const Eigen::Isometry3d& world_from_left, double t, uint64_t seed,
                      cv::Mat& left, cv::Mat& right);

}  // namespace osm_graph_slam::sim
