#include "osm_graph_slam/osm/osm_map_source.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "osm_graph_slam/common/polygon2d.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"

namespace osm_graph_slam {
namespace {

/// Equirectangular distance: only for coarse rejection (error well below 1 % within 100 km).
double approxDistance(const GeoPoint& a, const GeoPoint& b) {
  constexpr double kMetresPerDegree = 111195.0;
  const double dx = (b.lon - a.lon) * std::cos(0.5 * (a.lat + b.lat) * M_PI / 180.0);
  const double dy = b.lat - a.lat;
  return std::hypot(dx, dy) * kMetresPerDegree;
}

}  // namespace

double outlineDistance(const Polygon2& outline, const Eigen::Vector2d& p) {
  if (outline.empty()) return std::numeric_limits<double>::infinity();
  if (outline.size() >= 3 && pointInPolygon(p, outline)) return 0.0;
  return distanceToPolygon(p, outline);
}

// --- Overpass -------------------------------------------------------------------------------

OverpassMapSource::OverpassMapSource(OverpassParams params) : client_(std::move(params)) {}

std::string OverpassMapSource::describe() const {
  return "Overpass API at " + client_.params().endpoint;
}

MapFetchResult OverpassMapSource::fetch(const GeoPoint& centre, double radius_m) {
  MapFetchResult out;
  const OverpassResult answer = client_.fetchBuildings(centre.lat, centre.lon, radius_m);
  out.http_status = answer.http_status;
  out.elapsed_s = answer.elapsed_s;
  if (!answer.ok) {
    out.error = answer.error;
    out.error_kind = toString(answer.error_kind);
    if (answer.error_kind == OverpassError::kHttpStatus) {
      out.error_kind += "_" + std::to_string(answer.http_status);
    }
    return out;
  }
  OsmReadOptions options;
  options.read_roads = false;
  OsmData data = parseOsmXml(answer.body, options);
  if (!data.ok) {
    // A broken answer is not half-used: the buffer keeps its previous content instead.
    out.error = "Overpass answer from " + client_.params().endpoint +
                " is not valid OSM XML: " + data.error;
    out.error_kind = "malformed_response";
    return out;
  }
  out.ok = true;
  out.buildings = std::move(data.buildings);
  return out;
}

// --- local file -----------------------------------------------------------------------------

FileMapSource::FileMapSource(const std::string& path) : path_(path) {
  OsmReadOptions options;
  options.read_roads = false;
  OsmData data = readOsmFile(path, options);
  load_error_ = data.error;
  // A partly broken file still serves what was read; loadError() says what went wrong.
  loaded_ = data.ok || !data.buildings.empty();
  buildings_ = std::move(data.buildings);
  bounds_.reserve(buildings_.size());
  for (const Building& b : buildings_) {
    Bounds bounds;
    for (const GeoPoint& g : b.outline_geo) {
      bounds.centroid.lat += g.lat / b.outline_geo.size();
      bounds.centroid.lon += g.lon / b.outline_geo.size();
    }
    for (const GeoPoint& g : b.outline_geo) {
      bounds.radius_m = std::max(bounds.radius_m, approxDistance(bounds.centroid, g));
    }
    bounds_.push_back(bounds);
  }
}

std::string FileMapSource::describe() const {
  std::ostringstream s;
  s << "OSM file " << path_ << " (" << buildings_.size() << " buildings)";
  return s.str();
}

MapFetchResult FileMapSource::fetch(const GeoPoint& centre, double radius_m) {
  const auto start = std::chrono::steady_clock::now();
  MapFetchResult out;
  if (!loaded_) {
    out.error = "cannot serve buildings from " + path_ + ": " + load_error_;
    out.error_kind = "file_unreadable";
    return out;
  }
  const EnuConverter enu(centre.lat, centre.lon);
  for (size_t i = 0; i < buildings_.size(); ++i) {
    // Coarse reject with a generous margin, exact test in a local ENU frame.
    if (approxDistance(centre, bounds_[i].centroid) >
        1.02 * (radius_m + bounds_[i].radius_m) + 5.0) {
      continue;
    }
    Polygon2 outline;
    for (const GeoPoint& g : buildings_[i].outline_geo) outline.push_back(enu.toEnu(g));
    if (outlineDistance(outline, Eigen::Vector2d::Zero()) <= radius_m) {
      out.buildings.push_back(buildings_[i]);
    }
  }
  out.ok = true;
  out.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace osm_graph_slam
