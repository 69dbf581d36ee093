#pragma once
// The map package: what localisation on a saved map needs, in one versioned folder.
//
//   DIR/map.yaml                  format, version, ENU origin, counts, Scan Context parameters
//                                 (written last: a folder without it is refused)
//   DIR/map.pcd                   the map cloud (map frame = ENU at the origin), voxel-filtered
//   DIR/keyframes.csv             id stamp pose(3x4 row-major, base_link in map) per keyframe
//   DIR/keyframes/<id>.pcd        each keyframe's downsampled cloud in base_link
//   DIR/scan_context.csv          each keyframe's Scan Context cells (rings x sectors)
//   DIR/buildings_corrected.geojson  the corrected buildings (when there are any)
//
// writeMapPackage writes everything into DIR.partial-<pid> and renames it to DIR at the end, so
// a crash leaves no half-written DIR; loadMapPackage refuses a folder without map.yaml, another
// format or version, or missing/inconsistent files, with a message naming what is wrong.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/cloud_store.h"
#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/loop/scan_context.h"
#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

constexpr int kMapPackageVersion = 1;
constexpr const char* kMapPackageFormat = "osm_graph_slam_map";

struct MapKeyframe {
  uint64_t id = 0;
  double stamp = 0.0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< base_link in the map frame
  StoredCloud cloud;  ///< base_link (held, or read from the back-end's store when written)
  ScanContext descriptor;
};

struct MapPackage {
  int version = kMapPackageVersion;
  bool has_origin = false;
  double origin_lat = 0.0, origin_lon = 0.0, origin_alt = 0.0;
  double map_resolution = 0.0;  ///< [m] voxel of map_cloud (0: unfiltered)
  PointCloudConstPtr map_cloud;
  std::vector<MapKeyframe> keyframes;
  std::vector<Building> buildings;  ///< corrected; ENU filled on load when the origin is known
  ScanContextParams scan_context;   ///< the parameters the descriptors were made with
};

/// Writes the package atomically (see above). An existing DIR is replaced only once the new one
/// is complete. False with the reason in error.
bool writeMapPackage(const MapPackage& package, const std::string& directory, std::string* error);

/// Loads and checks a package. False with a clear reason for a missing folder, a folder without
/// map.yaml (half-written or not a package), another format, a version other than
/// kMapPackageVersion, or missing/inconsistent keyframe files.
bool loadMapPackage(const std::string& directory, MapPackage& package, std::string* error);

}  // namespace osm_graph_slam
