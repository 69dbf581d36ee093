#include "osm_graph_slam/osm/params_io.h"

#include <algorithm>

namespace osm_graph_slam {

void readParams(const ParamReader& r, OsmBufferParams& p) {
  r.param("buffer_radius", p.buffer_radius);
  r.param("query_radius", p.query_radius);
  r.param("refresh_distance", p.refresh_distance);
  r.param("retry_initial", p.retry_initial_s);
  r.param("retry_factor", p.retry_factor);
  r.param("retry_max", p.retry_max_s);
}

void readParams(const ParamReader& r, OverpassParams& p) {
  r.param("overpass_url", p.endpoint);
  r.param("overpass_timeout", p.timeout_s);
  r.param("overpass_connect_timeout", p.connect_timeout_s);
  r.param("overpass_server_timeout", p.server_timeout_s);
  r.param("overpass_max_retries", p.max_retries);
  r.param("overpass_backoff_initial", p.backoff_initial_s);
  r.param("overpass_backoff_factor", p.backoff_factor);
  r.param("overpass_backoff_max", p.backoff_max_s);
  r.param("overpass_user_agent", p.user_agent);
  // An int on the parameter server (XML-RPC has no 64-bit integers); at least one byte.
  int max_bytes = static_cast<int>(p.max_response_bytes);
  r.param("overpass_max_response_bytes", max_bytes);
  p.max_response_bytes = static_cast<size_t>(std::max(1, max_bytes));
  r.param("overpass_verify_tls", p.verify_tls);
}

}  // namespace osm_graph_slam
