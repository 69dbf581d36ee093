#include "osm_graph_slam/multi_cue/spherical_projection.h"

#include <algorithm>
#include <sstream>

namespace osm_graph_slam {

namespace {

constexpr double kDeg = M_PI / 180.0;

}  // namespace

SphericalProjectionParams SphericalProjectionParams::hdl64e() {
  SphericalProjectionParams p;
  p.rows = 64;
  p.cols = 1024;
  // Beams from +2.0 to -24.8 deg: 1/3 deg apart above -8.33 deg, 1/2 deg below.
  p.elevation_max = (2.0 + 0.2) * kDeg;
  p.elevation_min = (-24.8 - 0.25) * kDeg;
  return p;
}

SphericalProjectionParams SphericalProjectionParams::os1_64() {
  SphericalProjectionParams p;
  p.rows = 64;
  p.cols = 1024;
  const double half_spacing = 0.5 * 33.2 / 63.0;
  p.elevation_max = (16.6 + half_spacing) * kDeg;
  p.elevation_min = -(16.6 + half_spacing) * kDeg;
  p.min_range = 0.8;
  return p;
}

SphericalProjectionParams SphericalProjectionParams::halfScan(const SphericalProjectionParams& base,
                                                              double azimuth_start) {
  SphericalProjectionParams p = base;
  p.azimuth_span = M_PI;
  p.azimuth_start = azimuth_start;
  p.cols = base.cols * M_PI / base.azimuth_span;
  return p;
}

std::string SphericalProjectionParams::validate() const {
  std::ostringstream why;
  if (rows < 1 || cols < 1) {
    why << "the image needs at least one row and one column (rows " << rows << ", cols " << cols
        << ")";
  } else if (!std::isfinite(elevation_min) || !std::isfinite(elevation_max) ||
             !std::isfinite(azimuth_span) || !std::isfinite(azimuth_start) ||
             !std::isfinite(min_range) || !std::isfinite(max_range)) {
    why << "a field of view or range limit is not a finite number";
  } else if (elevation_max <= elevation_min) {
    why << "the vertical field of view is empty or inverted (elevation_min " << elevation_min
        << " rad >= elevation_max " << elevation_max << " rad)";
  } else if (elevation_min < -M_PI_2 || elevation_max > M_PI_2) {
    why << "the elevations must lie within [-pi/2, pi/2]";
  } else if (azimuth_span <= 0.0 || azimuth_span > 2.0 * M_PI + 1e-9) {
    why << "the horizontal field of view must be in (0, 2 pi] (azimuth_span " << azimuth_span
        << " rad)";
  } else if (min_range < 0.0 || min_range >= max_range) {
    why << "the range limits must satisfy 0 <= min_range < max_range (" << min_range << ", "
        << max_range << ")";
  }
  return why.str();
}

SphericalProjectionParams SphericalProjectionParams::coarser() const {
  SphericalProjectionParams p = *this;
  p.rows = std::max(1, rows / 2);
  p.cols = std::max(1, cols / 2);
  return p;
}

}  // namespace osm_graph_slam
