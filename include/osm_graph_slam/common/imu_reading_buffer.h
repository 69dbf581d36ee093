#pragma once
// One IMU quantity (body rates, or specific force) as a time series, averaged between two scans:
// what the localiser's prediction takes per scan. Used by the localization nodelet (live) and the
// bag reader of offline_localization (a whole bag at once).
#include <Eigen/Core>
#include <deque>
#include <optional>
#include <utility>

namespace osm_graph_slam {

class ImuReadingBuffer {
 public:
  /// keep_seconds > 0: readings older than that before the newest are dropped (live use).
  explicit ImuReadingBuffer(double keep_seconds = 0.0) : keep_seconds_(keep_seconds) {}

  /// A reading at stamp [s]; out-of-order readings are inserted in place, non-finite ignored.
  void add(double stamp, const Eigen::Vector3d& value);

  /// The mean of the readings in (from, to]; when none fell in the interval, the reading nearest
  /// to `to` within max_gap; nullopt when there is none either.
  std::optional<Eigen::Vector3d> meanBetween(double from, double to, double max_gap) const;

  size_t size() const { return readings_.size(); }

 private:
  double keep_seconds_;
  std::deque<std::pair<double, Eigen::Vector3d>> readings_;  ///< by stamp
};

}  // namespace osm_graph_slam
