#include "osm_graph_slam/slam/map_export.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "osm_graph_slam/cloud/map_cloud.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/common/upper_triangle.h"
#include "osm_graph_slam/common/xml_escape.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/map_server_files.h"
#include "osm_graph_slam/io/pcd_file.h"
#include "osm_graph_slam/io/staged_folder.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/grid_map.h"

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

/// Writes one save's files into a StagedFolder: each file is recorded, or the first failure.
struct Writer {
  MapExportResult& result;
  StagedFolder& folder;
  std::vector<std::string> names;
  std::string first_error;

  void operator()(const std::string& name, bool ok, const std::string& error) {
    if (ok)
      names.push_back(name);
    else if (first_error.empty())
      first_error = name + ": " + error;
  }
  std::string path(const std::string& name) const { return folder.stagedPath(name); }
  /// Moves the files into place if every one was written; otherwise the previous ones stay.
  bool finish() {
    if (!first_error.empty()) {
      result.message = first_error + " (nothing replaced: the previous files are unchanged)";
      return false;
    }
    if (!folder.commit(&first_error)) {
      result.message = "moving the written files into place failed: " + first_error;
      return false;
    }
    for (const auto& name : names) result.files.push_back(folder.finalPath(name));
    return true;
  }
};

std::string poseRow(const Eigen::Isometry3d& pose) {
  std::ostringstream os;
  os << std::setprecision(12);
  const Eigen::Matrix4d m = pose.matrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) os << (r || c ? " " : "") << m(r, c);
  return os.str();
}

/// A save must say when the map lacks keyframes the tracker made (an overflowed input queue).
std::string missingText(size_t missing) {
  return missing == 0 ? std::string()
                      : ", " + std::to_string(missing) + " keyframes missing (never received)";
}

/// map.pgm + map.yaml of `grid`, or of a grid built here from the keyframes. Returns a note for the
/// Appended to a save's or dump's message: where the keyframe clouds are, and how many could not
/// be read back from the back-end's store (those clouds are left out; the rest is written).
std::string cloudStoreNote(const GraphBackend& backend) {
  const CloudStoreStats s = backend.cloudStoreStats();
  char where[128];
  std::snprintf(where, sizeof(where), "; keyframe clouds: %zu on disk, %.0f MB in memory",
                s.on_disk, s.resident_bytes / (1024.0 * 1024.0));
  if (s.read_errors == 0) return where;
  return where +
         ("; " + std::to_string(s.read_errors) +
          " reads of keyframe clouds failed, those clouds left out (last: " + s.last_error + ")");
}

/// save's message: the build's cost per keyframe, or why no grid was written.
std::string writeGridMap(const GraphBackend& backend, const std::vector<KeyframeState>& keyframes,
                         const OccupancyGrid* grid, Writer& write) {
  const OccupancyGridParams& params = backend.params().grid;
  if (!grid && !params.enabled) return {};
  std::optional<OccupancyGrid> built;
  std::string note;
  if (!grid) {
    const std::string invalid = occupancyGridParamsError(params);
    if (!invalid.empty()) return "; no map.pgm: " + invalid;
    built.emplace(params);
    GridMapUpdate update = updateGridMap(*built, keyframes);
    grid = &*built;
    if (!update.insert_ms.empty()) {
      std::sort(update.insert_ms.begin(), update.insert_ms.end());
      std::ostringstream os;
      os << std::fixed << std::setprecision(2) << "; grid " << update.inserted << " keyframes, "
         << update.insert_ms[update.insert_ms.size() / 2] << " ms median, "
         << update.insert_ms.back() << " ms max per keyframe";
      note = os.str();
    }
  }
  const OccupancyGridImage image = grid->image();
  if (image.cells.empty()) return "; no map.pgm: no keyframe cloud gave a grid cell";
  std::string error;
  write("map.pgm", writeFileAtomically(write.path("map.pgm"), mapServerPgm(image), &error), error);
  write("map.yaml",
        writeFileAtomically(write.path("map.yaml"), mapServerYaml(image, "map.pgm"), &error),
        error);
  return note;
}

}  // namespace

PointCloudPtr buildMapCloud(const std::vector<KeyframeState>& keyframes, double resolution) {
  std::vector<PosedCloud> clouds;
  clouds.reserve(keyframes.size());
  for (const auto& kf : keyframes) clouds.push_back({kf.map_pose, kf.cloud});
  return mergeClouds(clouds, resolution);
}

MapPackage mapPackageFromBackend(const GraphBackend& backend, double resolution,
                                 const ScanContextParams& scan_context) {
  MapPackage p;
  const std::vector<KeyframeState> keyframes = backend.keyframes();
  p.map_cloud = buildMapCloud(keyframes, resolution);
  p.map_resolution = resolution;
  p.scan_context = scan_context;
  for (const auto& kf : keyframes) {
    if (kf.cloud.empty()) continue;
    const PointCloudConstPtr cloud = kf.cloud.load();
    if (!cloud) continue;  // unreadable from the store: counted there, shown in its stats
    MapKeyframe m;
    m.id = kf.id;
    m.stamp = kf.stamp;
    m.pose = kf.map_pose;
    m.cloud = kf.cloud;  // read again when written: the package never holds every cloud decoded
    m.descriptor = computeScanContext(*cloud, scan_context);
    p.keyframes.push_back(std::move(m));
  }
  if (const auto origin = backend.origin()) {
    p.has_origin = true;
    p.origin_lat = origin->originLat();
    p.origin_lon = origin->originLon();
    p.origin_alt = origin->originAlt();
    p.buildings = backend.correctedBuildings();
  }
  return p;
}

std::string buildingsToOsmXml(const std::vector<Building>& buildings) {
  std::ostringstream os;
  os << std::setprecision(10);
  os << "<?xml version='1.0' encoding='UTF-8'?>\n"
     << "<osm version='0.6' generator='osm_graph_slam'>\n";
  int64_t next_node = -1;
  std::ostringstream ways;
  int64_t next_way = -1;
  for (const auto& b : buildings) {
    if (b.outline_geo.size() < 3) continue;
    std::vector<int64_t> refs;
    for (const auto& g : b.outline_geo) {
      os << "  <node id='" << next_node << "' lat='" << g.lat << "' lon='" << g.lon << "'/>\n";
      refs.push_back(next_node--);
    }
    // Ways keep their OSM id; a building from a multipolygon relation becomes a new way that
    // names its relation.
    const bool way = b.id > 0;
    ways << "  <way id='" << (way ? b.id : next_way--) << "'";
    if (way) ways << " version='" << std::max(b.version, 1) << "'";
    ways << ">\n";
    for (int64_t r : refs) ways << "    <nd ref='" << r << "'/>\n";
    ways << "    <nd ref='" << refs.front() << "'/>\n";
    for (const auto& [k, v] : b.tags)
      ways << "    <tag k='" << xmlEscape(k) << "' v='" << xmlEscape(v) << "'/>\n";
    if (!b.tags.count("building")) ways << "    <tag k='building' v='yes'/>\n";
    if (!way) ways << "    <tag k='osm_graph_slam:relation' v='" << -b.id << "'/>\n";
    ways << "  </way>\n";
  }
  os << ways.str() << "</osm>\n";
  return os.str();
}

MapExportResult saveMap(const GraphBackend& backend, const std::string& directory,
                        double resolution, const ScanContextParams* scan_context,
                        const OccupancyGrid* grid) {
  MapExportResult result;
  const std::vector<KeyframeState> keyframes = backend.keyframes();
  if (keyframes.empty()) {
    result.message = "the graph is empty: no keyframe has been received yet";
    return result;
  }
  StagedFolder folder;
  if (!folder.open(directory, &result.message)) return result;
  Writer write{result, folder, {}, {}};
  std::string error;

  const PointCloudPtr map = buildMapCloud(keyframes, resolution);
  write("map.pcd", writePcdAtomically(write.path("map.pcd"), *map, &error), error);

  const std::vector<Building> buildings = backend.correctedBuildings();
  if (!buildings.empty()) {
    if (!backend.hasOrigin()) {
      write("buildings_corrected.geojson", false,
            "no GPS origin: corrected buildings cannot be given in lat/lon");
    } else {
      write("buildings_corrected.geojson",
            writeBuildingsGeoJson(write.path("buildings_corrected.geojson"), buildings, &error),
            error);
      write("buildings_corrected.osm",
            writeFileAtomically(write.path("buildings_corrected.osm"), buildingsToOsmXml(buildings),
                                &error),
            error);
    }
  }
  const Trajectory trajectory = backend.trajectory();
  write("trajectory_kitti.txt",
        writeKittiPoses(write.path("trajectory_kitti.txt"), trajectory, false, &error), error);
  write("trajectory_tum.txt",
        writeTumTrajectory(write.path("trajectory_tum.txt"), trajectory, &error), error);
  const G2oWriteResult g2o = writeG2o(backend.graphSnapshot(), write.path("graph.g2o"));
  write("graph.g2o", g2o.ok, g2o.message);
  write("map_package",
        writeMapPackage(mapPackageFromBackend(backend, resolution,
                                              scan_context ? *scan_context : ScanContextParams()),
                        write.path("map_package"), &error),
        error);
  // The graph itself, so that mapping can resume on this map (slam/map_resume.h).
  const MapExportResult graph = dumpGraph(backend, write.path("graph"));
  write("graph", graph.success, graph.message);
  const std::string grid_note = writeGridMap(backend, keyframes, grid, write);

  result.success = write.finish();
  if (result.success)
    result.message =
        "wrote " + std::to_string(result.files.size()) + " files (" + std::to_string(map->size()) +
        " map points, " + std::to_string(buildings.size()) + " buildings, " +
        std::to_string(keyframes.size()) + " keyframes" + missingText(backend.missingKeyframes()) +
        ")" + grid_note + cloudStoreNote(backend);
  return result;
}

MapExportResult dumpGraph(const GraphBackend& backend, const std::string& directory,
                          bool with_clouds) {
  MapExportResult result;
  const std::vector<KeyframeState> keyframes = backend.keyframes();
  if (keyframes.empty()) {
    result.message = "the graph is empty: no keyframe has been received yet";
    return result;
  }
  StagedFolder folder;
  if (!folder.open(directory, &result.message)) return result;
  std::error_code ec;
  if (with_clouds) fs::create_directories(fs::path(folder.stagedPath("keyframes")), ec);
  Writer write{result, folder, {}, {}};
  std::string error;

  std::ostringstream kf_csv, seg_csv;
  kf_csv << std::setprecision(17)
         << "# id stamp accum_distance odom_pose(3x4 row-major) odom_fitness imu_roll imu_pitch"
            " reanchored odom_hessian(upper triangle, row-major; zeros: unknown) "
            "prediction_error(x y z) gnss(x y std altitude) ins_yaw"
            " (nan: unknown)\n";
  seg_csv << std::setprecision(12) << "# keyframe_id x1 y1 x2 y2 support\n";
  std::ostringstream floor_csv;
  floor_csv << std::setprecision(17) << "# keyframe_id a b c d (floor plane under base_link)\n";
  for (const auto& kf : keyframes) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const Eigen::Vector2d rp = kf.gravity_roll_pitch.value_or(Eigen::Vector2d(nan, nan));
    kf_csv << kf.id << ' ' << kf.stamp << ' ' << kf.accum_distance << ' ' << poseRow(kf.odom_pose)
           << ' ' << kf.odom_fitness << ' ' << rp.x() << ' ' << rp.y() << ' '
           << (kf.reanchored ? 1 : 0);
    writeUpperTriangle(kf_csv, kf.odom_hessian);
    const Eigen::Vector3d& e = kf.odom_prediction_error;
    kf_csv << ' ' << e.x() << ' ' << e.y() << ' ' << e.z();
    // The GNSS and INS aiding, so that a replay can turn GNSS priors and heading edges on.
    const Eigen::Vector2d g = kf.gnss_position.value_or(Eigen::Vector2d(nan, nan));
    kf_csv << ' ' << g.x() << ' ' << g.y() << ' ' << kf.gnss_std.value_or(nan) << ' '
           << kf.gnss_altitude.value_or(nan) << ' ' << kf.ins_yaw.value_or(nan) << '\n';
    for (const auto& s : kf.segments)
      seg_csv << kf.id << ' ' << s.start.x() << ' ' << s.start.y() << ' ' << s.end.x() << ' '
              << s.end.y() << ' ' << s.support << '\n';
    if (kf.floor) {
      const Eigen::Vector4d& f = *kf.floor;
      floor_csv << kf.id << ' ' << f(0) << ' ' << f(1) << ' ' << f(2) << ' ' << f(3) << '\n';
    }
    if (with_clouds && !kf.cloud.empty()) {
      char name[64];
      std::snprintf(name, sizeof(name), "keyframes/%06lu.pcd", static_cast<unsigned long>(kf.id));
      // An unreadable cloud is left out (cloudStoreNote) rather than failing the whole dump.
      const PointCloudConstPtr cloud = kf.cloud.load();
      if (cloud) write(name, writePcdAtomically(write.path(name), *cloud, &error), error);
    }
  }
  write("keyframes.csv", writeFileAtomically(write.path("keyframes.csv"), kf_csv.str(), &error),
        error);
  write("segments.csv", writeFileAtomically(write.path("segments.csv"), seg_csv.str(), &error),
        error);
  write("floors.csv", writeFileAtomically(write.path("floors.csv"), floor_csv.str(), &error),
        error);

  std::ostringstream loops;
  loops << std::setprecision(17) << "# from_id to_id relative_pose(3x4) information(6x6)\n";
  for (const auto& l : backend.loopClosures()) {
    loops << l.from_id << ' ' << l.to_id << ' ' << poseRow(l.relative_pose);
    for (int i = 0; i < 36; ++i) loops << ' ' << l.information(i / 6, i % 6);
    loops << '\n';
  }
  write("loops.csv", writeFileAtomically(write.path("loops.csv"), loops.str(), &error), error);

  std::vector<Building> priors;
  for (const auto& b : backend.buildings()) priors.push_back(b.prior);
  write("buildings_prior.geojson",
        writeBuildingsGeoJson(write.path("buildings_prior.geojson"), priors, &error), error);
  if (const auto origin = backend.origin()) {
    std::ostringstream o;
    o << std::setprecision(12) << origin->originLat() << ' ' << origin->originLon() << ' '
      << origin->originAlt() << '\n';
    write("origin.txt", writeFileAtomically(write.path("origin.txt"), o.str(), &error), error);
  }
  {
    // Replays start from the heading the run started from. The first keyframe's optimised
    // heading would hand a replay the outcome it is meant to test (the OSM datum turns a run
    // about its anchor); it stands in only when no heading was known at the start.
    const double heading =
        backend.startHeading().value_or(planarPose(keyframes.front().map_pose).theta);
    std::ostringstream h;
    h << std::setprecision(17) << heading << '\n';
    write("initial_heading.txt",
          writeFileAtomically(write.path("initial_heading.txt"), h.str(), &error), error);
  }
  const G2oWriteResult g2o = writeG2o(backend.graphSnapshot(), write.path("graph.g2o"));
  write("graph.g2o", g2o.ok, g2o.message);

  result.success = write.finish();
  if (result.success)
    result.message = "dumped " + std::to_string(keyframes.size()) + " keyframes" +
                     missingText(backend.missingKeyframes()) + " in " +
                     std::to_string(result.files.size()) + " files" + cloudStoreNote(backend);
  return result;
}

}  // namespace osm_graph_slam
