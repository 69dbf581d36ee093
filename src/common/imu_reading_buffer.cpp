#include "osm_graph_slam/common/imu_reading_buffer.h"

#include <algorithm>
#include <cmath>

namespace osm_graph_slam {

namespace {
bool stampBefore(const std::pair<double, Eigen::Vector3d>& r, double stamp) {
  return r.first < stamp;
}
}  // namespace

void ImuReadingBuffer::add(double stamp, const Eigen::Vector3d& value) {
  if (!std::isfinite(stamp) || !value.allFinite()) return;
  if (readings_.empty() || readings_.back().first <= stamp)
    readings_.emplace_back(stamp, value);
  else
    readings_.insert(std::lower_bound(readings_.begin(), readings_.end(), stamp, stampBefore),
                     {stamp, value});
  if (keep_seconds_ > 0.0)
    while (readings_.front().first < readings_.back().first - keep_seconds_) readings_.pop_front();
}

std::optional<Eigen::Vector3d> ImuReadingBuffer::meanBetween(double from, double to,
                                                             double max_gap) const {
  // (from, to]: the first reading after `from` up to the first after `to`.
  auto first = std::upper_bound(readings_.begin(), readings_.end(), from,
                                [](double s, const auto& r) { return s < r.first; });
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (auto it = first; it != readings_.end() && it->first <= to; ++it) sum += it->second, ++count;
  if (count > 0) return sum / count;
  // None in the interval: the nearest to `to` on either side, within max_gap.
  const auto after = std::lower_bound(readings_.begin(), readings_.end(), to, stampBefore);
  std::optional<Eigen::Vector3d> nearest;
  double gap = max_gap;
  if (after != readings_.end() && after->first - to <= gap)
    gap = after->first - to, nearest = after->second;
  if (after != readings_.begin() && to - std::prev(after)->first <= gap)
    nearest = std::prev(after)->second;
  return nearest;
}

}  // namespace osm_graph_slam
