#pragma once
// A multi-cue image (MCS-SLAM, after Della Corte et al. 2018): a LiDAR scan projected
// spherically, with per pixel the nearest return's range, intensity, 3-D point and a normal
// computed from the range image; and its pyramid. The same image serves as the measurement of a
// scan and, once the scan is a keyframe, as the model rendered against later scans
// (doc/multi_cue.md).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/multi_cue/spherical_projection.h"

namespace osm_graph_slam {

struct MultiCueImage {
  enum Mask : uint8_t { kPoint = 1, kNormal = 2 };

  SphericalProjectionParams projection;
  std::vector<float> range;               ///< [m]; 0 where no return
  std::vector<float> intensity;           ///< the return's intensity; 0 where none
  std::vector<Eigen::Vector3f> point;     ///< the return in the sensor frame
  std::vector<Eigen::Vector3f> normal;    ///< unit, facing the sensor; zero where invalid
  std::vector<Eigen::Vector2f> subpixel;  ///< the return's continuous (u, v) inside its pixel
  std::vector<uint8_t> mask;              ///< Mask bits per pixel
  /// False when the cloud carried no intensity (every value zero or non-finite): the intensity
  /// cue is then off for this image.
  bool has_intensity = false;

  int rows() const { return projection.rows; }
  int cols() const { return projection.cols; }
  int index(int row, int col) const { return row * projection.cols + col; }
  bool hasPoint(int i) const { return mask[i] & kPoint; }
  bool hasNormal(int i) const { return mask[i] & kNormal; }
  size_t pointCount() const;
  size_t normalCount() const;
};

/// When neighbouring pixels belong to the same surface (normals, gradients).
struct SurfaceContinuityParams {
  /// Two neighbouring returns are on one surface when their ranges differ by less than this
  /// fraction of the nearer one. 0.10 keeps the ground between HDL-64E rows out to ~25 m and
  /// separates a pole from the wall behind it; on simulated scans with truth 0.05 / 0.10 / 0.15 /
  /// 0.25 gave 0.17 / 0.20 / 0.25 / 0.77 cm mean error (doc/multi_cue.md).
  double max_range_jump_ratio = 0.10;
};

/// True unless every intensity of the cloud is zero or non-finite (a cloud read from x, y, z
/// only carries zeros in PointXYZI's intensity).
bool cloudHasIntensity(const PointCloud& cloud);

/// Projects the cloud; where several points fall into one pixel the nearest wins (depth buffer).
/// The projections are computed on `num_threads` threads (0: all), the depth buffer filled in
/// the cloud's order, so the image does not depend on the thread count.
MultiCueImage projectCloud(const PointCloud& cloud, const SphericalProjectionParams& projection,
                           int num_threads = 1);
/// The same for bare points (the pyramid re-projects a finer level's returns so).
MultiCueImage projectPoints(const std::vector<Eigen::Vector3f>& points,
                            const std::vector<float>& intensity, bool has_intensity,
                            const SphericalProjectionParams& projection);

/// The normal of every pixel with a return, from the cross product of the vectors to its
/// horizontal and vertical neighbours on the same surface (the nearer in range of the two on each
/// side); pixels without such neighbours (depth discontinuities, isolated returns) keep no normal.
void computeNormals(MultiCueImage& image, const SurfaceContinuityParams& continuity,
                    int num_threads = 1);

/// Milliseconds spent per stage while building a pyramid.
struct MultiCueBuildTimes {
  double projection_ms = 0.0;
  double normals_ms = 0.0;
};

/// Level 0 is the finest (the given projection); each next level halves rows and columns
/// (SphericalProjectionParams::coarser) and re-projects the returns kept by the level above
/// through the depth buffer, so a coarse pixel holds one real return, never an average across a
/// depth edge.
struct MultiCuePyramid {
  std::vector<MultiCueImage> levels;
  bool has_intensity() const { return !levels.empty() && levels.front().has_intensity; }
};

MultiCuePyramid buildPyramid(const PointCloud& cloud, const SphericalProjectionParams& projection,
                             int levels, const SurfaceContinuityParams& continuity,
                             MultiCueBuildTimes* times = nullptr, int num_threads = 1);

}  // namespace osm_graph_slam
