#include "osm_graph_slam/osm/gnss_fix_lookup.h"

#include <algorithm>
#include <cmath>

namespace osm_graph_slam {

std::optional<GnssFixSample> gnssFixAt(const std::vector<GnssFixSample>& fixes, double stamp,
                                       double max_gap, double max_dt) {
  const auto after = std::lower_bound(fixes.begin(), fixes.end(), stamp,
                                      [](const GnssFixSample& f, double t) { return f.stamp < t; });
  if (after != fixes.end() && after != fixes.begin()) {
    const GnssFixSample& a = *(after - 1);
    const GnssFixSample& b = *after;
    const double gap = b.stamp - a.stamp;
    if (gap <= max_gap) {
      const double w = gap > 0.0 ? (stamp - a.stamp) / gap : 0.0;
      // Unknown (0) on either side stays unknown: the larger deviation of the two.
      const double std_xy = a.std_xy > 0.0 && b.std_xy > 0.0 ? std::max(a.std_xy, b.std_xy) : 0.0;
      return GnssFixSample{stamp, a.lat + w * (b.lat - a.lat), a.lon + w * (b.lon - a.lon),
                           a.alt + w * (b.alt - a.alt), std_xy};
    }
  }
  std::optional<GnssFixSample> nearest;
  double nearest_dt = max_dt;
  for (auto it : {after - (after != fixes.begin() ? 1 : 0), after}) {
    if (it == fixes.end()) continue;
    const double dt = std::abs(it->stamp - stamp);
    if (dt > nearest_dt) continue;
    nearest_dt = dt;
    nearest = *it;
  }
  return nearest;
}

}  // namespace osm_graph_slam
