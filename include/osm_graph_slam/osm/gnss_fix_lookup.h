#pragma once
// GNSS position at a given stamp from a sequence of fixes (the back-end anchors the first
// keyframe at it; the nodelet and offline_slam --bag share this lookup).
#include <optional>
#include <vector>

namespace osm_graph_slam {

struct GnssFixSample {
  double stamp = 0.0;  ///< [s]
  double lat = 0.0, lon = 0.0, alt = 0.0;
  double std_xy = 0.0;  ///< [m] horizontal standard deviation the receiver reports (0: unknown)
};

/// The fix at stamp: interpolated between the fixes around it when they are at most max_gap
/// apart, else the nearest fix within max_dt (the next fix may not have arrived yet), else
/// nullopt. fixes must be in stamp order.
std::optional<GnssFixSample> gnssFixAt(const std::vector<GnssFixSample>& fixes, double stamp,
                                       double max_gap, double max_dt);

}  // namespace osm_graph_slam
