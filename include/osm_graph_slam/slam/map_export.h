#pragma once
// What save_map and dump_graph write. Every file is written atomically (temporary file, then
// rename); a failure returns success = false with the reason and keeps the back-end untouched.
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/occupancy_grid.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/loop/scan_context.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

struct MapExportResult {
  bool success = false;
  std::string message;
  std::vector<std::string> files;
};

/// Keyframe clouds in the map frame, merged and reduced to voxel centroids (mergeClouds).
PointCloudPtr buildMapCloud(const std::vector<KeyframeState>& keyframes, double resolution);

/// The package of a back-end's current state: optimised keyframe poses and clouds, the map cloud
/// at `resolution`, corrected buildings, the origin; descriptors computed with scan_context.
MapPackage mapPackageFromBackend(const GraphBackend& backend, double resolution,
                                 const ScanContextParams& scan_context);

/// The corrected buildings as OSM XML: original way ids and tags, corrected coordinates (nodes
/// get new negative ids, as editors expect for new geometry). Loadable in JOSM.
std::string buildingsToOsmXml(const std::vector<Building>& buildings);

/// save_map: map.pcd, buildings_corrected.geojson, buildings_corrected.osm,
/// trajectory_kitti.txt, trajectory_tum.txt, graph.g2o, map_package/ (localization/
/// map_package.h: what offline_localization loads), graph/ (dump_graph's folder: what resumed
/// mapping replays, slam/map_resume.h), its Scan Context descriptors made with
/// scan_context (default parameters when null), and with grid_enabled map.pgm + map.yaml
/// (io/map_server_files.h): `grid` when given (the one the nodelet publishes), else one built from
/// the keyframes with the back-end's grid parameters.
MapExportResult saveMap(const GraphBackend& backend, const std::string& directory,
                        double resolution, const ScanContextParams* scan_context = nullptr,
                        const OccupancyGrid* grid = nullptr);

/// dump_graph: everything needed to rebuild and re-optimise the graph offline by replaying it
/// into a GraphBackend (keyframes.csv, keyframes/<id>.pcd, segments.csv, floors.csv, loops.csv,
/// buildings_prior.geojson, origin.txt) plus graph.g2o for inspection.
MapExportResult dumpGraph(const GraphBackend& backend, const std::string& directory,
                          bool with_clouds = true);

}  // namespace osm_graph_slam
