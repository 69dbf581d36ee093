// Reading a dump_graph directory (replaying it into a GraphBackend: graph_dump_replay.cpp, so
// that the reader links without the back-end, e.g. into fuzz/fuzz_graph_dump).
#include "osm_graph_slam/slam/graph_dump.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "osm_graph_slam/common/upper_triangle.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/pcd_file.h"
#include "osm_graph_slam/osm/enu_converter.h"

namespace osm_graph_slam {
namespace {

bool readPose(std::istringstream& in, Eigen::Isometry3d& pose) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      if (!(in >> m(r, c))) return false;
  pose.matrix() = m;
  return true;
}

/// Calls parse(line stream) for every non-comment line; false with file:line on the first error.
template <typename Parse>
bool forEachLine(const std::string& path, bool required, std::string* error, Parse parse) {
  std::ifstream file(path);
  if (!file) {
    if (required && error) *error = "cannot open " + path;
    return !required;
  }
  std::string line;
  for (int n = 1; std::getline(file, line); ++n) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    if (!parse(in)) {
      if (error) *error = path + ":" + std::to_string(n) + ": malformed line";
      return false;
    }
  }
  return true;
}

constexpr size_t kHessianValues = 21;  // upper triangle of the odometry match's 6x6 Hessian

}  // namespace

bool readGraphDump(const std::string& dir, GraphDump& dump, std::string* error) {
  dump = GraphDump{};
  auto keyframe = [&](std::istringstream& in) {
    KeyframeInput kf;
    if (!(in >> kf.id >> kf.stamp >> kf.accum_distance) || !readPose(in, kf.odom_pose))
      return false;
    // Optional columns (older dumps lack them): fitness, IMU roll and pitch ("nan" when there
    // was none, which operator>> cannot read, so the tokens go through strtod), re-anchored.
    std::vector<double> extra;
    for (std::string token; in >> token;) {
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') return false;
      extra.push_back(v);
    }
    if (extra.size() >= 3) {
      kf.odom_fitness = extra[0];
      if (std::isfinite(extra[1]) && std::isfinite(extra[2]))
        kf.gravity_roll_pitch.emplace(extra[1], extra[2]);
    }
    if (extra.size() >= 4) kf.reanchored = extra[3] != 0.0;
    if (extra.size() >= 4 + kHessianValues) {
      kf.odom_hessian = upperTriangleToMatrix(extra, 4, 6);
      if (!kf.odom_hessian.allFinite()) return false;
    }
    if (extra.size() >= 7 + kHessianValues) {
      const size_t first = 4 + kHessianValues;
      kf.odom_prediction_error = {extra[first], extra[first + 1], extra[first + 2]};
      if (!kf.odom_prediction_error.allFinite()) return false;
    }
    if (extra.size() >= 12 + kHessianValues) {  // GNSS x y std altitude, INS yaw (nan: none)
      const double* a = &extra[7 + kHessianValues];
      if (std::isfinite(a[0]) && std::isfinite(a[1])) kf.gnss_position.emplace(a[0], a[1]);
      if (std::isfinite(a[2]) && a[2] > 0.0) kf.gnss_std = a[2];
      if (std::isfinite(a[3])) kf.gnss_altitude = a[3];
      if (std::isfinite(a[4])) kf.ins_yaw = a[4];
    }
    dump.keyframes.push_back(std::move(kf));
    return true;
  };
  auto segment = [&](std::istringstream& in) {
    uint64_t id;
    double x1, y1, x2, y2, support = 0.0;
    if (!(in >> id >> x1 >> y1 >> x2 >> y2)) return false;
    // Optional (older dumps lack it); a count: negative, NaN or huge is a malformed line (the
    // cast to unsigned was undefined behaviour, fuzz_graph_dump).
    if (std::string token; in >> token) {
      char* end = nullptr;
      support = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0' ||
          !(support >= 0.0 && support <= std::numeric_limits<unsigned>::max()))
        return false;
    }
    LineSegment2 s({x1, y1}, {x2, y2});
    s.support = static_cast<unsigned>(support);
    dump.segments[id].push_back(s);
    return true;
  };
  std::map<uint64_t, Eigen::Vector4d> floors;
  auto floor = [&](std::istringstream& in) {
    uint64_t id;
    Eigen::Vector4d f;
    if (!(in >> id >> f(0) >> f(1) >> f(2) >> f(3)) || !f.allFinite()) return false;
    floors[id] = f;
    return true;
  };
  auto loop = [&](std::istringstream& in) {
    LoopClosureInput l;
    if (!(in >> l.from_id >> l.to_id) || !readPose(in, l.relative_pose)) return false;
    for (int i = 0; i < 36; ++i)
      if (!(in >> l.information(i / 6, i % 6))) return false;
    dump.loops.push_back(l);
    return true;
  };
  auto origin = [&](std::istringstream& in) {
    Eigen::Vector3d o;
    if (!(in >> o.x() >> o.y() >> o.z())) return false;
    dump.origin = o;
    return true;
  };
  auto heading = [&](std::istringstream& in) {
    double yaw;
    if (!(in >> yaw)) return false;
    dump.initial_heading = yaw;
    return true;
  };
  if (!forEachLine(dir + "/keyframes.csv", true, error, keyframe) ||
      !forEachLine(dir + "/segments.csv", false, error, segment) ||
      !forEachLine(dir + "/floors.csv", false, error, floor) ||
      !forEachLine(dir + "/loops.csv", false, error, loop) ||
      !forEachLine(dir + "/origin.txt", false, error, origin) ||
      !forEachLine(dir + "/initial_heading.txt", false, error, heading))
    return false;
  const BuildingFileResult buildings = readBuildingsGeoJson(dir + "/buildings_prior.geojson");
  if (buildings.ok) {
    dump.buildings = buildings.buildings;
    if (dump.origin) {
      const EnuConverter enu(dump.origin->x(), dump.origin->y(), dump.origin->z());
      for (auto& b : dump.buildings) enu.project(b);
    }
  }
  if (dump.keyframes.empty()) {
    if (error) *error = dir + "/keyframes.csv holds no keyframe";
    return false;
  }
  // Floors of keyframes the dump does not hold are ignored, as the back-end drops them.
  for (auto& kf : dump.keyframes)
    if (auto it = floors.find(kf.id); it != floors.end()) kf.floor = it->second;
  return true;
}

size_t loadDumpClouds(const std::string& dir, GraphDump& dump, std::string* error) {
  size_t missing = 0;
  for (auto& kf : dump.keyframes) {
    char name[64];
    std::snprintf(name, sizeof(name), "/keyframes/%06lu.pcd", static_cast<unsigned long>(kf.id));
    auto cloud = std::make_shared<PointCloud>();
    std::string why;
    if (readPcd(dir + name, *cloud, &why)) {
      kf.cloud = std::move(cloud);
    } else {
      if (missing++ == 0 && error) *error = why;
    }
  }
  return missing;
}

}  // namespace osm_graph_slam
