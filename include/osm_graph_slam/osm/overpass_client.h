#pragma once
// A small libcurl client for the Overpass API (OSM thesis §2.5.1 / §3.1): a QL query for the
// buildings around a position, with timeouts, retries with exponential back-off, gzip, a size
// cap and cancellation. Never throws; every failure is described in the result.
#include <atomic>
#include <cstddef>
#include <string>

namespace osm_graph_slam {

struct OverpassParams {
  std::string endpoint = "https://overpass-api.de/api/interpreter";
  double timeout_s = 30.0;          ///< whole transfer, per attempt
  double connect_timeout_s = 10.0;  ///< TCP/TLS connect, per attempt
  int server_timeout_s = 25;        ///< [timeout:N] asked of the Overpass server
  int max_retries = 3;              ///< attempts after the first one (transient faults only)
  double backoff_initial_s = 1.0;   ///< wait before the first retry
  double backoff_factor = 2.0;      ///< growth of the wait per retry
  double backoff_max_s = 30.0;      ///< cap of a single wait (also caps Retry-After)
  std::string user_agent = "osm_graph_slam/0.1 (ROS OSM-prior graph SLAM)";
  size_t max_response_bytes = 64u << 20;  ///< decompressed body; larger answers are aborted
  bool verify_tls = true;
};

/// Why a request failed; the buffer logs each kind once.
enum class OverpassError {
  kNone,
  kConnect,        ///< could not connect / resolve / TLS
  kTimeout,        ///< no complete answer within timeout_s
  kTransfer,       ///< connection dropped or broken stream
  kHttpStatus,     ///< non-200 HTTP status
  kTooLarge,       ///< body exceeded max_response_bytes
  kServerRuntime,  ///< HTTP 200 with an Overpass "runtime error" remark
  kCancelled,
  kOther,
};

const char* toString(OverpassError error);

struct OverpassResult {
  bool ok = false;
  long http_status = 0;  ///< last HTTP status (0 when no response)
  OverpassError error_kind = OverpassError::kNone;
  std::string error;  ///< human-readable reason (empty when ok)
  std::string body;   ///< decompressed response body (the OSM XML when ok)
  int attempts = 0;
  double elapsed_s = 0.0;
};

class OverpassClient {
 public:
  explicit OverpassClient(OverpassParams params = {});

  /// Overpass QL: building ways and multipolygon relations with any part within radius_m of
  /// (lat, lon), then their member ways and nodes so the answer is self-contained.
  static std::string buildingsQuery(double lat, double lon, double radius_m, int server_timeout_s);

  OverpassResult fetchBuildings(double lat, double lon, double radius_m) const;
  /// POSTs a QL query (form field "data") with retries. Blocking; never throws.
  OverpassResult post(const std::string& query) const;

  /// Aborts an in-flight request and any pending back-off wait (from another thread).
  void cancel() { cancelled_ = true; }
  void resetCancel() { cancelled_ = false; }

  const OverpassParams& params() const { return params_; }

 private:
  OverpassResult attempt(const std::string& query, double* retry_after_s) const;
  bool sleepUnlessCancelled(double seconds) const;

  OverpassParams params_;
  mutable std::atomic<bool> cancelled_{false};
};

}  // namespace osm_graph_slam
