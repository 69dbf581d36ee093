#pragma once
// A rectified stereo pair (D3VIL-SLAM's visual branch, ART-SLAM thesis §6.1): both images share
// the intrinsics and the rows; the right camera sits `baseline` to the right of the left one.
#include <Eigen/Core>
#include <optional>
#include <string>

namespace osm_graph_slam {

struct StereoCamera {
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  ///< [px]
  double baseline = 0.0;                          ///< [m]

  /// The left camera's point at pixel (u, v) with disparity d (u_left - u_right) [px].
  Eigen::Vector3d triangulate(double u, double v, double disparity) const {
    const double z = fx * baseline / disparity;
    return {(u - cx) * z / fx, (v - cy) * z / fy, z};
  }
  /// The left image pixel of a point in the left camera's frame (z > 0).
  Eigen::Vector2d project(const Eigen::Vector3d& p) const {
    return {fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy};
  }
};

/// KITTI odometry calib.txt: the rows "P0: ..." and "P1: ..." (or the first two unkeyed rows; 3 x
/// 4, row-major; P1's fourth column is -fx * baseline). Null with the reason when a row is missing
/// or malformed.
std::optional<StereoCamera> readKittiStereoCalibration(const std::string& path, std::string* error);

}  // namespace osm_graph_slam
