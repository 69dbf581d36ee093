#pragma once
// Where OsmBuffer gets its buildings: the Overpass API or a local whole-city .osm/.osm.pbf,
// behind one interface so the SLAM side does not care (ART-SLAM §5.1.4, OSM thesis §3.1).
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/osm/overpass_client.h"

namespace osm_graph_slam {

struct MapFetchResult {
  bool ok = false;
  std::string error;       ///< why the fetch failed (ok == false)
  std::string error_kind;  ///< short stable key of the failure kind (for log-once)
  long http_status = 0;
  std::vector<Building> buildings;  ///< outline_geo filled; ENU fields are the caller's job
  double elapsed_s = 0.0;
};

class OsmMapSource {
 public:
  virtual ~OsmMapSource() = default;
  /// Buildings with any part of their outline within radius_m of centre. Blocking (runs on the
  /// buffer's worker thread); never throws.
  virtual MapFetchResult fetch(const GeoPoint& centre, double radius_m) = 0;
  /// Aborts a fetch in progress (called from another thread at shutdown).
  virtual void cancel() {}
  virtual std::string describe() const = 0;
};

/// Distance from p to a closed outline: 0 inside, else to the nearest edge (ENU metres).
double outlineDistance(const Polygon2& outline, const Eigen::Vector2d& p);

/// Buildings from the Overpass API (one `around` query per fetch, parsed with libosmium).
class OverpassMapSource : public OsmMapSource {
 public:
  explicit OverpassMapSource(OverpassParams params = {});
  MapFetchResult fetch(const GeoPoint& centre, double radius_m) override;
  void cancel() override { client_.cancel(); }
  std::string describe() const override;

 private:
  OverpassClient client_;
};

/// Buildings of a local .osm / .osm.pbf file read once at construction (offline use).
class FileMapSource : public OsmMapSource {
 public:
  explicit FileMapSource(const std::string& path);
  bool loaded() const { return loaded_; }
  const std::string& loadError() const { return load_error_; }
  size_t size() const { return buildings_.size(); }
  MapFetchResult fetch(const GeoPoint& centre, double radius_m) override;
  std::string describe() const override;

 private:
  struct Bounds {
    GeoPoint centroid;
    double radius_m = 0.0;  ///< bounding circle around the centroid
  };
  std::string path_;
  bool loaded_ = false;
  std::string load_error_;
  std::vector<Building> buildings_;
  std::vector<Bounds> bounds_;
};

}  // namespace osm_graph_slam
