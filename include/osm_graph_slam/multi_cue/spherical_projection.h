#pragma once
// The spherical projection of a spinning LiDAR (MCS-SLAM's cloud projector, doc/multi_cue.md):
// a point maps to the continuous pixel (u, v) = K [azimuth, elevation, 1], with u growing with
// the azimuth from the image's left edge and v growing downwards from the highest elevation.
// Pixel (row, col) covers u in [col, col + 1) and v in [row, row + 1).
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

namespace osm_graph_slam {

struct SphericalProjectionParams {
  int rows = 64;
  int cols = 1024;
  /// Elevation of the image's bottom and top edges [rad]: the lowest and highest beams plus
  /// half a beam spacing, so that the outer beams fall inside.
  double elevation_min = -25.0 * M_PI / 180.0;
  double elevation_max = 2.2 * M_PI / 180.0;
  /// Horizontal field of view [rad]: 2 pi for a full revolution, less for a sensor that sees a
  /// sector (a half scan: pi).
  double azimuth_span = 2.0 * M_PI;
  /// Azimuth of the image's left edge [rad], measured counter-clockwise from +x.
  double azimuth_start = -M_PI;
  double min_range = 2.0;    ///< returns closer than this are dropped (the car body) [m]
  double max_range = 120.0;  ///< [m]

  /// Velodyne HDL-64E (KITTI): 64 rows over +2.0 ... -24.8 deg, 1024 columns (the sensor fires
  /// ~2083 per revolution; half of that keeps a pixel per return on most rows).
  static SphericalProjectionParams hdl64e();
  /// Ouster OS1-64: 64 x 1024, 64 beams uniformly over +/-16.6 deg.
  static SphericalProjectionParams os1_64();
  /// One half of a 360 deg sensor (the thesis's "front" or "back" LiDAR): `base` restricted to
  /// the 180 deg sector that starts at azimuth_start, with half the columns.
  static SphericalProjectionParams halfScan(const SphericalProjectionParams& base,
                                            double azimuth_start);

  /// "" when usable, else what is wrong (rows or columns < 1, a non-finite value, an empty or
  /// inverted field of view, a span above 2 pi, min_range >= max_range).
  std::string validate() const;
  /// The next pyramid level: half the rows and columns over the same field of view.
  SphericalProjectionParams coarser() const;

  bool fullCircle() const { return azimuth_span >= 2.0 * M_PI - 1e-9; }
  double colsPerRadian() const { return cols / azimuth_span; }
  double rowsPerRadian() const { return rows / (elevation_max - elevation_min); }
  int size() const { return rows * cols; }

  /// Continuous pixel coordinates and range of p; false when p is outside the field of view or
  /// the range limits.
  bool project(const Eigen::Vector3f& p, float* u, float* v, float* range) const {
    const float rho2 = p.x() * p.x() + p.y() * p.y();
    const float r = std::sqrt(rho2 + p.z() * p.z());
    if (!(r >= min_range && r <= max_range)) return false;  // also rejects NaN
    float azimuth = fastAtan2(p.y(), p.x()) - static_cast<float>(azimuth_start);
    if (azimuth < 0.0f) azimuth += static_cast<float>(2.0 * M_PI);
    if (azimuth >= static_cast<float>(2.0 * M_PI)) azimuth -= static_cast<float>(2.0 * M_PI);
    const float col = azimuth * static_cast<float>(colsPerRadian());
    const float row = (static_cast<float>(elevation_max) - fastAtan2(p.z(), std::sqrt(rho2))) *
                      static_cast<float>(rowsPerRadian());
    if (!(col >= 0.0f && col < cols && row >= 0.0f && row < rows)) return false;
    *u = col;
    *v = row;
    *range = r;
    return true;
  }

  /// d(u, v) / dp at p (p off the z axis): the chain rule's projection step.
  template <typename Scalar>
  Eigen::Matrix<Scalar, 2, 3> projectionJacobian(const Eigen::Matrix<Scalar, 3, 1>& p) const {
    const Scalar rho2 = p.x() * p.x() + p.y() * p.y();
    const Scalar rho = std::sqrt(rho2);
    const Scalar r2 = rho2 + p.z() * p.z();
    const Scalar fu = static_cast<Scalar>(colsPerRadian());
    const Scalar fv = static_cast<Scalar>(rowsPerRadian());
    const Scalar fv_rho_r2 = fv / (r2 * rho);
    Eigen::Matrix<Scalar, 2, 3> j;
    j << -fu * p.y() / rho2, fu * p.x() / rho2, Scalar(0),  // d azimuth
        p.x() * p.z() * fv_rho_r2, p.y() * p.z() * fv_rho_r2, -fv * rho / r2;
    return j;
  }

  /// atan2 to within 1.2e-5 rad (a column of a 1024-column image is 6e-3 rad) at a fraction of
  /// std::atan2's cost: the projection runs for every return of a scan and for every model point
  /// in every Gauss-Newton iteration. Abramowitz & Stegun 4.4.48 (atan on [0, 1]), then the
  /// octant.
  static float fastAtan2(float y, float x) {
    const float ax = std::abs(x), ay = std::abs(y);
    const float big = std::max(ax, ay);
    if (big == 0.0f) return 0.0f;
    const float a = std::min(ax, ay) / big;
    const float s = a * a;
    float r = a * (0.9998660f +
                   s * (-0.3302995f + s * (0.1801410f + s * (-0.0851330f + s * 0.0208351f))));
    if (ay > ax) r = static_cast<float>(M_PI_2) - r;
    if (x < 0.0f) r = static_cast<float>(M_PI) - r;
    return y < 0.0f ? -r : r;
  }
};

}  // namespace osm_graph_slam
