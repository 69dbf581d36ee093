#include "osm_graph_slam/slam/graph_dump.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "osm_graph_slam/io/building_geojson.h"
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
    dump.keyframes.push_back(std::move(kf));
    return true;
  };
  auto segment = [&](std::istringstream& in) {
    uint64_t id;
    double x1, y1, x2, y2, support = 0.0;
    if (!(in >> id >> x1 >> y1 >> x2 >> y2)) return false;
    in >> support;
    LineSegment2 s({x1, y1}, {x2, y2});
    s.support = static_cast<unsigned>(support);
    dump.segments[id].push_back(s);
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
  return true;
}

BackendUpdateReport replayGraphDump(const GraphDump& dump, GraphBackend& backend,
                                    int optimize_every) {
  if (dump.origin) backend.setOrigin(dump.origin->x(), dump.origin->y(), dump.origin->z());
  if (!dump.buildings.empty()) backend.addBuildings(dump.buildings, Eigen::Vector2d::Zero(), 1e9);
  std::multimap<uint64_t, const LoopClosureInput*> loops_by_from;
  for (const auto& l : dump.loops) loops_by_from.emplace(l.from_id, &l);
  BackendUpdateReport report, total;
  auto accumulate = [&](const BackendUpdateReport& r) {
    total.building_edges += r.building_edges;
    total.local_attempts += r.local_attempts;
    total.local_unseen += r.local_unseen;
    total.local_rejected += r.local_rejected;
    total.global_priors += r.global_priors;
    total.global_rejected += r.global_rejected;
  };
  int since_update = 0;
  for (const auto& kf : dump.keyframes) {
    backend.addKeyframe(kf);
    auto segs = dump.segments.find(kf.id);
    if (segs != dump.segments.end()) backend.addLineSegments(kf.id, segs->second);
    auto range = loops_by_from.equal_range(kf.id);
    for (auto it = range.first; it != range.second; ++it) backend.addLoopClosure(*it->second);
    if (++since_update >= std::max(1, optimize_every)) {
      accumulate(backend.update());
      since_update = 0;
    }
  }
  report = backend.update(true);
  accumulate(report);
  // Counts summed over every update; the optimisation results are the last update's.
  report.building_edges = total.building_edges;
  report.local_attempts = total.local_attempts;
  report.local_unseen = total.local_unseen;
  report.local_rejected = total.local_rejected;
  report.global_priors = total.global_priors;
  report.global_rejected = total.global_rejected;
  return report;
}

}  // namespace osm_graph_slam
