#include "osm_graph_slam/localization/map_package.h"

#include <pcl/io/pcd_io.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/pcd_file.h"
#include "osm_graph_slam/io/staged_folder.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/loop/params_io.h"
#include "osm_graph_slam/osm/enu_converter.h"

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

bool fail(std::string* error, const std::string& why) {
  if (error) *error = why;
  return false;
}

std::string keyframeCloudName(uint64_t id) {
  char name[64];
  std::snprintf(name, sizeof(name), "keyframes/%06lu.pcd", static_cast<unsigned long>(id));
  return name;
}

std::string poseRow(const Eigen::Isometry3d& pose) {
  std::ostringstream os;
  os << std::setprecision(17);
  const Eigen::Matrix4d m = pose.matrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) os << (r || c ? " " : "") << m(r, c);
  return os.str();
}

std::string mapYaml(const MapPackage& p) {
  std::ostringstream y;
  y << std::setprecision(17);
  y << "# osm_graph_slam map package (doc/localization.md); written last, after every other file\n"
    << "format: " << kMapPackageFormat << "\n"
    << "version: " << p.version << "\n"
    << "has_origin: " << (p.has_origin ? "true" : "false") << "\n"
    << "origin:\n"
    << "  lat: " << p.origin_lat << "\n"
    << "  lon: " << p.origin_lon << "\n"
    << "  alt: " << p.origin_alt << "\n"
    << "map_cloud: map.pcd\n"
    << "map_points: " << (p.map_cloud ? p.map_cloud->size() : 0) << "\n"
    << "map_resolution: " << p.map_resolution << "\n"
    << "keyframes: " << p.keyframes.size() << "\n"
    << "buildings: " << p.buildings.size() << "\n"
    << "scan_context:\n"
    << "  num_rings: " << p.scan_context.num_rings << "\n"
    << "  num_sectors: " << p.scan_context.num_sectors << "\n"
    << "  max_radius: " << p.scan_context.max_radius << "\n"
    << "  min_radius: " << p.scan_context.min_radius << "\n"
    << "  sensor_height: " << p.scan_context.sensor_height << "\n"
    << "  max_height: " << p.scan_context.max_height << "\n"
    << "  min_height: " << p.scan_context.min_height << "\n"
    << "  sector_search_window: " << p.scan_context.sector_search_window << "\n";
  return y.str();
}

}  // namespace

bool writeMapPackage(const MapPackage& package, const std::string& directory, std::string* error) {
  if (directory.empty()) return fail(error, "no map package folder given");
  if (!package.map_cloud || package.map_cloud->empty())
    return fail(error, "the map cloud is empty: nothing to localise against");
  if (package.keyframes.empty()) return fail(error, "the map has no keyframes");
  fs::path target = fs::absolute(directory);
  if (target.filename().empty()) target = target.parent_path();
  const fs::path partial = target.string() + ".partial-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(partial, ec);
  fs::create_directories(partial / "keyframes", ec);
  if (ec) return fail(error, "cannot create '" + partial.string() + "': " + ec.message());
  const auto abandon = [&](const std::string& why) {
    std::error_code ignored;
    fs::remove_all(partial, ignored);
    return fail(error, why);
  };
  std::string why;
  if (!writePcdAtomically((partial / "map.pcd").string(), *package.map_cloud, &why))
    return abandon(why);

  std::ostringstream kf_csv, sc_csv;
  kf_csv << std::setprecision(17) << "# id stamp pose(3x4 row-major: base_link in map)\n";
  sc_csv << std::setprecision(9) << "# id then rings x sectors cells, row-major\n";
  for (const auto& kf : package.keyframes) {
    if (kf.cloud.empty()) return abandon("keyframe " + std::to_string(kf.id) + " has no cloud");
    const PointCloudConstPtr cloud = kf.cloud.load(&why);
    if (!cloud || !writePcdAtomically((partial / keyframeCloudName(kf.id)).string(), *cloud, &why))
      return abandon(why);
    kf_csv << kf.id << ' ' << kf.stamp << ' ' << poseRow(kf.pose) << '\n';
    sc_csv << kf.id;
    const Eigen::MatrixXf& c = kf.descriptor.cells;
    for (int r = 0; r < c.rows(); ++r)
      for (int s = 0; s < c.cols(); ++s) sc_csv << ' ' << c(r, s);
    sc_csv << '\n';
  }
  if (!writeFileAtomically((partial / "keyframes.csv").string(), kf_csv.str(), &why))
    return abandon(why);
  if (!writeFileAtomically((partial / "scan_context.csv").string(), sc_csv.str(), &why))
    return abandon(why);
  if (!package.buildings.empty() &&
      !writeBuildingsGeoJson((partial / "buildings_corrected.geojson").string(), package.buildings,
                             &why))
    return abandon(why);
  // map.yaml last: a folder without it was not finished.
  if (!writeFileAtomically((partial / "map.yaml").string(), mapYaml(package), &why))
    return abandon(why);

  if (!replacePath(partial.string(), target.string(), &why)) return abandon(why);
  return true;
}

bool loadMapPackage(const std::string& directory, MapPackage& package, std::string* error) {
  package = MapPackage();
  const fs::path dir(directory);
  if (!fs::is_directory(dir)) return fail(error, "map package '" + directory + "' does not exist");
  const fs::path yaml_path = dir / "map.yaml";
  if (!fs::exists(yaml_path))
    return fail(error, "'" + directory +
                           "' has no map.yaml: not a map package, or a half-written one (map.yaml "
                           "is written last); write it again with offline_slam or save_map");
  const YamlParamReader yaml = YamlParamReader::fromFile(yaml_path.string());
  if (!yaml.ok()) return fail(error, "'" + yaml_path.string() + "': " + yaml.error());
  std::string format;
  if (!yaml.getString("format", &format) || format != kMapPackageFormat)
    return fail(error, "'" + yaml_path.string() + "' is not an " + kMapPackageFormat +
                           " file (format: '" + format + "')");
  int version = -1;
  if (!yaml.getInt("version", &version) || version != kMapPackageVersion)
    return fail(error, "map package '" + directory + "' has version " + std::to_string(version) +
                           ", this program reads version " + std::to_string(kMapPackageVersion) +
                           " only");
  package.version = version;
  yaml.getBool("has_origin", &package.has_origin);
  yaml.getDouble("origin/lat", &package.origin_lat);
  yaml.getDouble("origin/lon", &package.origin_lon);
  yaml.getDouble("origin/alt", &package.origin_alt);
  yaml.getDouble("map_resolution", &package.map_resolution);
  readParams(PrefixedParamReader(yaml, "scan_context"), package.scan_context);
  int expected_keyframes = -1, expected_points = -1, expected_buildings = 0;
  yaml.getInt("keyframes", &expected_keyframes);
  yaml.getInt("map_points", &expected_points);
  yaml.getInt("buildings", &expected_buildings);

  auto map = std::make_shared<PointCloud>();
  const fs::path map_path = dir / "map.pcd";
  if (!fs::exists(map_path) || pcl::io::loadPCDFile(map_path.string(), *map) != 0)
    return fail(error, "map package '" + directory + "': cannot read map.pcd");
  if (expected_points >= 0 && map->size() != static_cast<size_t>(expected_points))
    return fail(error, "map package '" + directory + "': map.pcd has " +
                           std::to_string(map->size()) + " points, map.yaml says " +
                           std::to_string(expected_points));
  package.map_cloud = map;

  std::ifstream kf_in((dir / "keyframes.csv").string());
  if (!kf_in) return fail(error, "map package '" + directory + "': no keyframes.csv");
  std::string line;
  while (std::getline(kf_in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream is(line);
    MapKeyframe kf;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    is >> kf.id >> kf.stamp;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) is >> m(r, c);
    if (!is)
      return fail(error, "map package '" + directory + "': malformed line in keyframes.csv: '" +
                             line + "'");
    kf.pose.linear() = m.topLeftCorner<3, 3>();
    kf.pose.translation() = m.topRightCorner<3, 1>();
    // Read once to check it, then read again where it is used: a package of a long drive does
    // not hold every keyframe's cloud in memory (doc/long_drives.md).
    PointCloud cloud;
    const std::string cloud_path = (dir / keyframeCloudName(kf.id)).string();
    if (!fs::exists(cloud_path) || pcl::io::loadPCDFile(cloud_path, cloud) != 0)
      return fail(error, "map package '" + directory + "': cannot read " + cloud_path);
    kf.cloud = StoredCloud(
        [cloud_path](std::string* why) -> PointCloudConstPtr {
          auto c = std::make_shared<PointCloud>();
          if (pcl::io::loadPCDFile(cloud_path, *c) == 0) return c;
          if (why) *why = "cannot read " + cloud_path;
          return nullptr;
        },
        cloud.size());
    package.keyframes.push_back(std::move(kf));
  }
  if (package.keyframes.empty() ||
      (expected_keyframes >= 0 && package.keyframes.size() != size_t(expected_keyframes)))
    return fail(error, "map package '" + directory + "': keyframes.csv lists " +
                           std::to_string(package.keyframes.size()) + " keyframes, map.yaml says " +
                           std::to_string(expected_keyframes));

  // Descriptors: stored cells when they are complete and of the stated size, else recomputed.
  const int rings = package.scan_context.num_rings, sectors = package.scan_context.num_sectors;
  std::ifstream sc_in((dir / "scan_context.csv").string());
  size_t next = 0;
  while (sc_in && std::getline(sc_in, line) && next < package.keyframes.size()) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream is(line);
    uint64_t id = 0;
    is >> id;
    Eigen::MatrixXf cells(rings, sectors);
    for (int r = 0; r < rings; ++r)
      for (int s = 0; s < sectors; ++s) is >> cells(r, s);
    if (!is || id != package.keyframes[next].id) break;
    package.keyframes[next++].descriptor = scanContextFromCells(cells);
  }
  for (; next < package.keyframes.size(); ++next) {
    std::string why;
    const PointCloudConstPtr cloud = package.keyframes[next].cloud.load(&why);
    if (!cloud) return fail(error, "map package '" + directory + "': " + why);
    package.keyframes[next].descriptor = computeScanContext(*cloud, package.scan_context);
  }

  const fs::path buildings_path = dir / "buildings_corrected.geojson";
  if (expected_buildings > 0 || fs::exists(buildings_path)) {
    BuildingFileResult b = readBuildingsGeoJson(buildings_path.string());
    if (!b.ok)
      return fail(error,
                  "map package '" + directory + "': buildings_corrected.geojson: " + b.error);
    if (package.has_origin) {
      const EnuConverter enu(package.origin_lat, package.origin_lon, package.origin_alt);
      for (auto& building : b.buildings) enu.project(building);
    }
    package.buildings = std::move(b.buildings);
  }
  return true;
}

}  // namespace osm_graph_slam
