#include "osm_graph_slam/sim/prior_map.h"
#include "osm_graph_slam/common/xml_escape.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/lines/line_geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

Eigen::Vector2d vertexMean(const Polygon2& poly) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : poly) c += p;
  return poly.empty() ? c : Eigen::Vector2d(c / double(poly.size()));
}

std::string jsonEscape(const std::string& s) {
  std::string out;
  for (char ch : s) {
    if (ch == '"' || ch == '\\') out += '\\';
    out += ch;
  }
  return out;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

}  // namespace

bool parsePriorModel(const std::string& name, PriorModel& model) {
  for (PriorModel m :
       {PriorModel::kIndependent, PriorModel::kBlocks, PriorModel::kGlobal, PriorModel::kMixed}) {
    if (name == priorModelName(m)) {
      model = m;
      return true;
    }
  }
  return false;
}

const char* priorModelName(PriorModel model) {
  switch (model) {
    case PriorModel::kIndependent:
      return "independent";
    case PriorModel::kBlocks:
      return "blocks";
    case PriorModel::kGlobal:
      return "global";
    case PriorModel::kMixed:
      return "mixed";
  }
  return "independent";
}

namespace {

/// Rigid 2D map p -> R p + t.
struct Rigid2 {
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity();
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  double theta = 0.0;
  /// Rotation by theta about centre c, then a shift by d.
  static Rigid2 about(const Eigen::Vector2d& c, double theta, const Eigen::Vector2d& d) {
    Rigid2 T;
    T.theta = theta;
    T.R = Pose2(0, 0, theta).rotation();
    T.t = c + d - T.R * c;
    return T;
  }
  /// this after other.
  Rigid2 operator*(const Rigid2& other) const {
    Rigid2 T;
    T.theta = theta + other.theta;
    T.R = R * other.R;
    T.t = R * other.t + t;
    return T;
  }
  Eigen::Vector2d operator()(const Eigen::Vector2d& p) const { return R * p + t; }
};

/// Axis-aligned bounds of an outline.
struct Bounds {
  Eigen::Vector2d lo{1e18, 1e18}, hi{-1e18, -1e18};
  explicit Bounds(const Polygon2& poly) {
    for (const auto& v : poly) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
};

bool outlinesTouch(const Polygon2& a, const Polygon2& b, double tolerance) {
  for (const auto& v : a)
    if (distanceToPolygon(v, b) <= tolerance) return true;
  for (const auto& v : b)
    if (distanceToPolygon(v, a) <= tolerance) return true;
  return false;
}

int findRoot(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

constexpr uint64_t kBlockTag = 0x626c6f636b73ULL;   // "blocks"
constexpr uint64_t kGlobalTag = 0x676c6f62616cULL;  // "global"

}  // namespace

std::vector<int> priorBlockGroups(const Scene& scene, const PriorPerturbationParams& p) {
  const auto& buildings = scene.world.buildings;
  const int n = int(buildings.size());
  // Connected components of touching outlines: a sweep along x over the bounds.
  std::vector<Bounds> bounds;
  for (const auto& b : buildings) bounds.emplace_back(b.outline);
  std::vector<int> order(n), parent(n);
  for (int i = 0; i < n; ++i) order[i] = parent[i] = i;
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return bounds[a].lo.x() < bounds[b].lo.x(); });
  const double tol = std::max(0.0, p.block_touch_distance);
  for (int ii = 0; ii < n; ++ii) {
    const int i = order[ii];
    for (int jj = ii + 1; jj < n; ++jj) {
      const int j = order[jj];
      if (bounds[j].lo.x() > bounds[i].hi.x() + tol) break;
      if (bounds[j].lo.y() > bounds[i].hi.y() + tol || bounds[i].lo.y() > bounds[j].hi.y() + tol)
        continue;
      if (findRoot(parent, i) == findRoot(parent, j)) continue;
      if (outlinesTouch(buildings[i].outline, buildings[j].outline, tol))
        parent[findRoot(parent, i)] = findRoot(parent, j);
    }
  }
  // Each component goes to the grid cell of its vertex mean; a cell is one group.
  std::map<int, std::pair<Eigen::Vector2d, size_t>> sums;
  for (int i = 0; i < n; ++i) {
    auto& s =
        sums.emplace(findRoot(parent, i), std::make_pair(Eigen::Vector2d::Zero(), 0)).first->second;
    for (const auto& v : buildings[i].outline) s.first += v;
    s.second += buildings[i].outline.size();
  }
  std::map<std::pair<int64_t, int64_t>, int> cell_group;
  std::map<int, int> component_group;
  std::vector<int> group(n, -1);
  for (int i = 0; i < n; ++i) {
    const int root = findRoot(parent, i);
    auto it = component_group.find(root);
    if (it == component_group.end()) {
      const auto& s = sums.at(root);
      const Eigen::Vector2d c = s.first / double(std::max<size_t>(s.second, 1));
      std::pair<int64_t, int64_t> cell{-1 - int64_t(root), 0};  // no grid: the component alone
      if (p.block_size > 0.0)
        cell = {int64_t(std::floor(c.x() / p.block_size)),
                int64_t(std::floor(c.y() / p.block_size))};
      const int next = int(cell_group.size());
      const int g = cell_group.emplace(cell, next).first->second;
      it = component_group.emplace(root, g).first;
    }
    group[i] = it->second;
  }
  return group;
}

std::vector<PriorBuilding> perturbBuildings(const Scene& scene, const PriorPerturbationParams& p,
                                            PriorMapInfo* info) {
  const auto& buildings = scene.world.buildings;
  const size_t n = buildings.size();
  SimRng rng(hashCombine(p.seed, 0x7072696f72ULL));
  // Exactly round(fraction * n) removals, chosen by a deterministic shuffle.
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  for (size_t i = n; i > 1; --i) std::swap(order[i - 1], order[rng.next() % i]);
  const size_t removed = size_t(std::llround(p.removal_fraction * double(n)));
  std::vector<bool> is_removed(n, false);
  for (size_t i = 0; i < removed && i < n; ++i) is_removed[order[i]] = true;

  // Group offsets (blocks, global) from streams of their own: the per-building draws below stay
  // the same whatever the model.
  const bool use_blocks = p.model == PriorModel::kBlocks || p.model == PriorModel::kMixed;
  const bool use_global = p.model == PriorModel::kGlobal || p.model == PriorModel::kMixed;
  Rigid2 global;
  if (use_global && n > 0) {
    SimRng g(hashCombine(p.seed, kGlobalTag));
    const double dir = g.uniform(-M_PI, M_PI);
    const double mag = g.uniform(p.global_offset_min, p.global_offset_max);
    const double th = p.global_rotation_sigma_deg * M_PI / 180.0 * g.gaussian();
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    size_t count = 0;
    for (const auto& b : buildings) {
      for (const auto& v : b.outline) c += v;
      count += b.outline.size();
    }
    c /= double(std::max<size_t>(count, 1));
    global = Rigid2::about(c, th, mag * Eigen::Vector2d(std::cos(dir), std::sin(dir)));
    if (info) {
      info->global_offset = mag * Eigen::Vector2d(std::cos(dir), std::sin(dir));
      info->global_rotation = th;
    }
  }
  std::vector<Rigid2> block_of(n);
  if (use_blocks) {
    const std::vector<int> group = priorBlockGroups(scene, p);
    int groups = 0;
    for (int g : group) groups = std::max(groups, g + 1);
    std::vector<Eigen::Vector2d> sum(groups, Eigen::Vector2d::Zero());
    std::vector<size_t> count(groups, 0);
    for (size_t i = 0; i < n; ++i) {
      for (const auto& v : buildings[i].outline) sum[group[i]] += v;
      count[group[i]] += buildings[i].outline.size();
    }
    std::vector<Rigid2> offsets(groups);
    for (int g = 0; g < groups; ++g) {
      // Seeded by the group's first building id: the offset does not depend on the order.
      int64_t first_id = 0;
      for (size_t i = 0; i < n; ++i) {
        if (group[i] == g) {
          first_id = buildings[i].osm_id;
          break;
        }
      }
      SimRng r(hashCombine(hashCombine(p.seed, kBlockTag), uint64_t(first_id)));
      const double dx = p.block_translation_sigma * r.gaussian();
      const double dy = p.block_translation_sigma * r.gaussian();
      const double th = p.block_rotation_sigma_deg * M_PI / 180.0 * r.gaussian();
      offsets[g] = Rigid2::about(sum[g] / double(std::max<size_t>(count[g], 1)), th,
                                 Eigen::Vector2d(dx, dy));
    }
    for (size_t i = 0; i < n; ++i) block_of[i] = offsets[group[i]];
    if (info) info->groups = size_t(groups);
  }
  // Sigma of the per-building part of each model.
  double own_sigma = p.translation_sigma, own_rot_deg = p.rotation_sigma_deg;
  if (p.model == PriorModel::kBlocks) {
    own_sigma = p.block_residual_sigma;
    own_rot_deg = p.block_residual_rotation_sigma_deg;
  } else if (p.model == PriorModel::kGlobal) {
    own_sigma = own_rot_deg = 0.0;
  } else if (p.model == PriorModel::kMixed) {
    own_sigma = p.mixed_translation_sigma;
    own_rot_deg = p.mixed_rotation_sigma_deg;
  }

  std::vector<PriorBuilding> prior;
  for (size_t i = 0; i < n; ++i) {
    PriorBuilding b;
    b.osm_id = buildings[i].osm_id;
    b.tags = i < scene.building_tags.size() ? scene.building_tags[i] : OsmTags{{"building", "yes"}};
    b.centroid = vertexMean(buildings[i].outline);
    // Draw the offset even for removed buildings so removal does not shift other offsets.
    b.dx = own_sigma * rng.gaussian();
    b.dy = own_sigma * rng.gaussian();
    b.dtheta = own_rot_deg * M_PI / 180.0 * rng.gaussian();
    if (p.model == PriorModel::kIndependent) {
      if (is_removed[i]) {
        b.status = PriorBuilding::Status::kRemoved;
      } else {
        const Eigen::Matrix2d R = Pose2(0, 0, b.dtheta).rotation();
        for (const auto& v : buildings[i].outline) {
          b.outline.push_back(R * (v - b.centroid) + b.centroid + Eigen::Vector2d(b.dx, b.dy));
        }
      }
      prior.push_back(b);
      continue;
    }
    // global after block after own: one rigid map, applied to every vertex the same way (so
    // vertices shared by buildings of one group stay bit-identical when own is zero).
    const Rigid2 own = Rigid2::about(b.centroid, b.dtheta, Eigen::Vector2d(b.dx, b.dy));
    const Rigid2 T = global * (block_of[i] * own);
    b.dtheta = T.theta;
    const Eigen::Vector2d d = T(b.centroid) - b.centroid;
    b.dx = d.x();
    b.dy = d.y();
    if (is_removed[i]) {
      b.status = PriorBuilding::Status::kRemoved;
    } else {
      for (const auto& v : buildings[i].outline) b.outline.push_back(T(v));
    }
    prior.push_back(b);
  }

  // Phantoms: rectangles in free space (clear of true buildings and roads).
  const size_t phantoms = size_t(std::llround(p.phantom_fraction * double(n)));
  Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (const auto& b : buildings) {
    for (const auto& v : b.outline) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  int64_t next_id = 9000000000LL;
  for (size_t k = 0, attempts = 0; k < phantoms && attempts < 20000 && n > 0; ++attempts) {
    const Eigen::Vector2d c(rng.uniform(lo.x(), hi.x()), rng.uniform(lo.y(), hi.y()));
    const double hx = rng.uniform(5.0, 12.0), hy = rng.uniform(4.0, 8.0),
                 th = rng.uniform(-M_PI, M_PI);
    const Eigen::Matrix2d R = Pose2(0, 0, th).rotation();
    Polygon2 poly;
    for (const auto& corner : {Eigen::Vector2d(-hx, -hy), Eigen::Vector2d(hx, -hy),
                               Eigen::Vector2d(hx, hy), Eigen::Vector2d(-hx, hy)}) {
      poly.push_back(c + R * corner);
    }
    const double reach = std::hypot(hx, hy) + 2.0;
    bool clear = true;
    for (const auto& b : buildings) {
      if (!clear) break;
      for (const auto& v : b.outline) {
        if ((v - c).norm() < reach) clear = false;
      }
      if (distanceToPolygon(c, b.outline) < reach) clear = false;
    }
    for (const auto& road : scene.roads) {
      for (size_t i = 0; clear && i + 1 < road.size(); ++i) {
        const Eigen::Vector2d a = road[i], e = road[i + 1] - a;
        const double t = std::clamp((c - a).dot(e) / std::max(e.squaredNorm(), 1e-12), 0.0, 1.0);
        if ((a + t * e - c).norm() < reach + 6.0) clear = false;
      }
    }
    if (!clear) continue;
    PriorBuilding b;
    b.status = PriorBuilding::Status::kPhantom;
    b.osm_id = next_id++;
    b.outline = poly;
    b.tags = {{"building", "yes"}};
    b.centroid = c;
    prior.push_back(b);
    ++k;
  }
  return prior;
}

bool writePriorOsm(const std::string& path, const std::vector<PriorBuilding>& prior,
                   const Scene& scene, const EnuConverter& enu, std::string* error) {
  std::ostringstream nodes, ways;
  int64_t node_id = 1;
  double min_lat = 90, max_lat = -90, min_lon = 180, max_lon = -180;
  auto addNode = [&](const Eigen::Vector2d& p) {
    const GeoPoint g = enu.toGeoPoint(p);
    min_lat = std::min(min_lat, g.lat);
    max_lat = std::max(max_lat, g.lat);
    min_lon = std::min(min_lon, g.lon);
    max_lon = std::max(max_lon, g.lon);
    nodes << "  <node id=\"" << node_id << "\" version=\"1\" lat=\"" << fmt("%.9f", g.lat)
          << "\" lon=\"" << fmt("%.9f", g.lon) << "\"/>\n";
    return node_id++;
  };
  auto addWay = [&](int64_t id, const std::vector<int64_t>& refs, const OsmTags& tags) {
    ways << "  <way id=\"" << id << "\" version=\"1\">\n";
    for (int64_t r : refs) ways << "    <nd ref=\"" << r << "\"/>\n";
    for (const auto& [k, v] : tags) {
      ways << "    <tag k=\"" << xmlEscape(k) << "\" v=\"" << xmlEscape(v) << "\"/>\n";
    }
    ways << "  </way>\n";
  };
  // Building vertices at identical coordinates are one node (neighbours moved together keep the
  // nodes they share in the truth).
  std::map<std::pair<double, double>, int64_t> building_nodes;
  for (const auto& b : prior) {
    if (b.status == PriorBuilding::Status::kRemoved || b.outline.size() < 3) continue;
    std::vector<int64_t> refs;
    for (const auto& v : b.outline) {
      const auto it = building_nodes.find({v.x(), v.y()});
      refs.push_back(it != building_nodes.end() ? it->second
                                                : building_nodes[{v.x(), v.y()}] = addNode(v));
    }
    refs.push_back(refs.front());
    OsmTags tags = b.tags;
    if (!tags.count("building")) tags["building"] = "yes";
    addWay(b.osm_id, refs, tags);
  }
  auto addRoads = [&](const std::vector<Polyline2>& roads, const std::vector<int64_t>& ids,
                      const std::vector<std::string>& types) {
    for (size_t i = 0; i < roads.size(); ++i) {
      std::vector<int64_t> refs;
      for (const auto& v : roads[i]) refs.push_back(addNode(v));
      addWay(ids[i], refs, {{"highway", types[i]}});
    }
  };
  // Road ways share nodes in the source; here each way gets its own nodes at identical
  // coordinates, which the reader's road graph merges by position.
  addRoads(scene.roads, scene.road_ids, scene.road_types);
  addRoads(scene.other_roads, scene.other_road_ids, scene.other_road_types);
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<osm version=\"0.6\" generator=\"osm_graph_slam simulate_urban\">\n"
      << "  <bounds minlat=\"" << fmt("%.9f", min_lat) << "\" minlon=\"" << fmt("%.9f", min_lon)
      << "\" maxlat=\"" << fmt("%.9f", max_lat) << "\" maxlon=\"" << fmt("%.9f", max_lon)
      << "\"/>\n"
      << nodes.str() << ways.str() << "</osm>\n";
  return writeFileAtomically(path, out.str(), error);
}

bool writePriorOffsetsCsv(const std::string& path, const std::vector<PriorBuilding>& prior,
                          std::string* error) {
  std::ostringstream out;
  out << "# prior = R(dtheta) * (true - centroid) + centroid + (dx, dy); ENU of the simulation\n"
      << "osm_id,status,dx_m,dy_m,dtheta_deg,centroid_x,centroid_y\n";
  for (const auto& b : prior) {
    const char* status = b.status == PriorBuilding::Status::kPerturbed ? "perturbed"
                         : b.status == PriorBuilding::Status::kRemoved ? "removed"
                                                                       : "phantom";
    out << b.osm_id << ',' << status << ',' << fmt("%.6f", b.dx) << ',' << fmt("%.6f", b.dy) << ','
        << fmt("%.6f", b.dtheta * 180.0 / M_PI) << ',' << fmt("%.4f", b.centroid.x()) << ','
        << fmt("%.4f", b.centroid.y()) << '\n';
  }
  return writeFileAtomically(path, out.str(), error);
}

bool writeBuildingsGeoJson(const std::string& path, const Scene& scene, const EnuConverter& enu,
                           std::string* error) {
  std::ostringstream out;
  out << "{\"type\":\"FeatureCollection\",\"enu_origin\":{\"lat\":" << fmt("%.9f", enu.originLat())
      << ",\"lon\":" << fmt("%.9f", enu.originLon()) << ",\"alt\":" << fmt("%.3f", enu.originAlt())
      << "},\"features\":[\n";
  const auto& buildings = scene.world.buildings;
  for (size_t i = 0; i < buildings.size(); ++i) {
    const auto& b = buildings[i];
    std::ostringstream geo, local;
    for (size_t k = 0; k <= b.outline.size(); ++k) {
      const Eigen::Vector2d& v = b.outline[k % b.outline.size()];
      const GeoPoint g = enu.toGeoPoint(v);
      geo << (k ? "," : "") << '[' << fmt("%.9f", g.lon) << ',' << fmt("%.9f", g.lat) << ']';
      local << (k ? "," : "") << '[' << fmt("%.4f", v.x()) << ',' << fmt("%.4f", v.y()) << ']';
    }
    std::string name;
    if (i < scene.building_tags.size()) {
      auto it = scene.building_tags[i].find("name");
      if (it != scene.building_tags[i].end()) name = it->second;
    }
    out << "{\"type\":\"Feature\",\"properties\":{\"osm_id\":" << b.osm_id
        << ",\"height_m\":" << fmt("%.2f", b.height) << ",\"name\":\"" << jsonEscape(name)
        << "\",\"outline_enu\":[" << local.str()
        << "]},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[[" << geo.str() << "]]}}"
        << (i + 1 < buildings.size() ? ",\n" : "\n");
  }
  out << "]}\n";
  return writeFileAtomically(path, out.str(), error);
}

}  // namespace osm_graph_slam::sim
