#pragma once
// Floor detection (ART-SLAM §3.1.6): the ground plane under the vehicle in one filtered cloud.
// Clip a height band and a ring around the vehicle, keep points whose normals are near vertical
// (walls, windows and car sides are planes too), RANSAC a plane and refine it by least squares.
// Rough terrain, where RANSAC finds no plane with enough support, falls back to a least-squares
// fit of the points nearest the vehicle. PCL stays in the .cpp.
#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <string>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct FloorDetectorParams {
  bool enabled = true;
  /// Where the floor is expected in the cloud's frame (base_link) and how far from it a floor
  /// point may lie (slopes and pitch raise or lower the ground at range) [m].
  double floor_z = -0.93;
  double floor_z_tolerance = 0.6;
  double min_range = 2.0;             ///< [m] horizontal; the vehicle's own body and the blind ring
  double max_range = 20.0;            ///< [m] horizontal; far ground bends with the terrain
  int normal_neighbours = 10;         ///< k of the normal estimation
  double max_normal_tilt_deg = 20.0;  ///< points with a normal tilted more are not floor
  double ransac_distance = 0.08;      ///< [m] inlier band of the RANSAC plane
  int ransac_iterations = 200;
  int min_inliers = 300;             ///< less support: no RANSAC floor
  double max_floor_tilt_deg = 15.0;  ///< a steeper "floor" is a ramp wall or a mistake
  /// Rough-terrain fallback: least squares on the candidates within this radius [m] (0: off).
  double rough_radius = 6.0;
  int rough_min_points = 100;
  double rough_max_rms = 0.1;  ///< [m] a worse least-squares fit is no floor
  /// One warning when this many keyframes in a row have no floor (the caller counts).
  int warn_after_missing = 10;
};

struct FloorDetection {
  bool found = false;
  /// a x + b y + c z + d = 0 in the cloud's frame, (a, b, c) unit with c > 0.
  Eigen::Vector4d coeffs = Eigen::Vector4d(0.0, 0.0, 1.0, 0.0);
  std::string method;  ///< "ransac" or "least_squares" (rough terrain)
  size_t candidates = 0, inliers = 0;
  double rms = 0.0;    ///< [m] of the inliers' distances from the plane
  std::string reason;  ///< why no floor, when !found
};

class FloorDetector {
 public:
  explicit FloorDetector(const FloorDetectorParams& params = {}) : params_(params) {}
  FloorDetection detect(const PointCloud& cloud) const;
  const FloorDetectorParams& params() const { return params_; }

 private:
  FloorDetectorParams params_;
};

/// Counts keyframes with and without a floor, so that a floor lost for long is said once: one
/// message when warn_after keyframes in a row have none, one when a floor is found again.
class FloorHealth {
 public:
  explicit FloorHealth(int warn_after = 10) : warn_after_(std::max(1, warn_after)) {}
  /// A message to log (warning), or empty.
  std::string update(uint64_t keyframe, const FloorDetection& detection);
  size_t found() const { return found_; }
  size_t missing() const { return missing_; }
  size_t warnings() const { return warnings_; }

 private:
  int warn_after_;
  size_t found_ = 0, missing_ = 0, warnings_ = 0;
  int run_ = 0;  ///< keyframes in a row without a floor
};

/// Tilt of a plane's normal from the frame's z axis [rad].
double floorTilt(const Eigen::Vector4d& coeffs);

}  // namespace osm_graph_slam
