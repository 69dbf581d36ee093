#pragma once
// OSM building buffer of the OSM thesis §3.1: a large buffer (120 m) is fetched around the
// vehicle, every keyframe asks for a small radius (35 m) and is answered from memory; when the
// vehicle is more than 60 m from the buffer centre a new buffer is fetched in the background
// while the old one keeps answering. Queries never wait on the network.
#include <Eigen/Core>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "osm_graph_slam/common/logger.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_map_source.h"

namespace osm_graph_slam {

struct OsmBufferParams {
  double buffer_radius = 120.0;    ///< [m] radius fetched around the vehicle
  double query_radius = 35.0;      ///< [m] default radius of a keyframe query
  double refresh_distance = 60.0;  ///< [m] distance from the buffer centre that triggers a refill
  double retry_initial_s = 2.0;    ///< wait after a failed fill before trying again
  double retry_factor = 2.0;       ///< growth of that wait per consecutive failure
  double retry_max_s = 60.0;       ///< cap of that wait
};

struct OsmQueryResult {
  bool buffer_valid = false;  ///< false until the first successful fill
  uint64_t generation = 0;    ///< increments on every successful fill
  Eigen::Vector2d buffer_centre = Eigen::Vector2d::Zero();  ///< ENU
  bool refill_in_flight = false;
  std::vector<Building> buildings;  ///< ENU-projected, outline within the radius
};

struct OsmBufferStats {
  bool has_data = false;
  uint64_t generation = 0;
  size_t buildings = 0;  ///< in the buffer
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  size_t fills_ok = 0;
  size_t fills_failed = 0;
  size_t consecutive_failures = 0;
  bool refill_in_flight = false;
  std::string last_error;
  double last_fetch_s = 0.0;
};

class OsmBuffer {
 public:
  /// logger may be null (stderr). enu is the map frame (origin = first GPS fix).
  OsmBuffer(std::shared_ptr<OsmMapSource> source, const EnuConverter& enu,
            const OsmBufferParams& params = {}, std::shared_ptr<const Logger> logger = nullptr);
  ~OsmBuffer();
  OsmBuffer(const OsmBuffer&) = delete;
  OsmBuffer& operator=(const OsmBuffer&) = delete;

  /// Never blocks: answers from the current buffer and, if the position is farther than
  /// refresh_distance from its centre (or there is no buffer yet), starts a background refill
  /// unless one is running or the retry back-off after a failure has not elapsed.
  OsmQueryResult query(const Eigen::Vector2d& position);
  OsmQueryResult query(const Eigen::Vector2d& position, double radius);

  /// Blocking fill around position (startup, tools). Returns true if this fill succeeded.
  bool fillBlocking(const Eigen::Vector2d& position, double timeout_s = 120.0);
  /// Waits until no refill is pending or running. Returns false on timeout.
  bool waitForIdle(double timeout_s) const;

  OsmBufferStats stats() const;
  const OsmBufferParams& params() const { return params_; }
  const EnuConverter& enu() const { return enu_; }

 private:
  using Clock = std::chrono::steady_clock;
  struct Snapshot {
    Eigen::Vector2d centre;
    uint64_t generation = 0;
    std::vector<Building> buildings;  // projected
  };

  bool requestLocked(const Eigen::Vector2d& position, bool ignore_backoff);
  void workerLoop();
  void handleResult(const Eigen::Vector2d& centre, MapFetchResult result);
  void warnCoverage(const Snapshot& snap, const Eigen::Vector2d& position, double radius) const;

  std::shared_ptr<OsmMapSource> source_;
  EnuConverter enu_;
  OsmBufferParams params_;
  std::shared_ptr<const Logger> logger_;

  mutable std::mutex mutex_;
  std::condition_variable request_cv_;
  mutable std::condition_variable idle_cv_;
  std::shared_ptr<const Snapshot> snapshot_;
  std::optional<Eigen::Vector2d> pending_;
  bool in_flight_ = false;
  bool stop_ = false;
  Clock::time_point next_retry_ = Clock::time_point::min();
  double retry_wait_s_;
  OsmBufferStats stats_;
  std::set<std::string> failure_keys_;  // log-once keys to clear after the next success
  mutable bool coverage_warned_ = false;
  std::thread worker_;
};

}  // namespace osm_graph_slam
