#include "osm_graph_slam/sim/scene.h"

#include "downtown.h"

#include "osm_graph_slam/common/cell_key.h"
#include "osm_graph_slam/sim/forest_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <unordered_map>

#include "osm_graph_slam/common/polygon2d.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Uniform hash of segments for "is anything within r of p" queries.
class SegmentHash {
 public:
  explicit SegmentHash(double cell = 10.0) : cell_(cell) {}
  void add(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const int id = int(segs_.size());
    segs_.push_back({a, b});
    const Eigen::Vector2d lo = a.cwiseMin(b), hi = a.cwiseMax(b);
    for (long long y = key(lo.y()); y <= key(hi.y()); ++y) {
      for (long long x = key(lo.x()); x <= key(hi.x()); ++x) cells_[pack(x, y)].push_back(id);
    }
  }
  void addPolyline(const Polyline2& line, bool closed = false) {
    for (size_t i = 0; i + 1 < line.size(); ++i) add(line[i], line[i + 1]);
    if (closed && line.size() > 2) add(line.back(), line.front());
  }
  /// Smallest distance from p to a segment, looking only within radius (else +inf).
  double nearest(const Eigen::Vector2d& p, double radius) const {
    double best = kInf;
    for (long long y = key(p.y() - radius); y <= key(p.y() + radius); ++y) {
      for (long long x = key(p.x() - radius); x <= key(p.x() + radius); ++x) {
        auto it = cells_.find(pack(x, y));
        if (it == cells_.end()) continue;
        for (int id : it->second) {
          best = std::min(best,
                          pointSegmentDistance(p, LineSegment2(segs_[id].first, segs_[id].second)));
        }
      }
    }
    return best <= radius ? best : kInf;
  }

 private:
  long long key(double v) const { return static_cast<long long>(std::floor(v / cell_)); }
  static long long pack(long long x, long long y) { return packCellKey(x, y); }
  double cell_;
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segs_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

struct Circle {
  Eigen::Vector2d c;
  double r;
};

/// Everything placed clutter must stay away from.
class PlacementChecker {
 public:
  PlacementChecker(const Scene& scene, const Trajectory* route, const ClutterParams& params)
      : scene_(scene), params_(params) {
    for (const auto& b : scene.world.buildings) walls_.addPolyline(b.outline, true);
    for (const auto& r : scene.roads) roads_.addPolyline(r);
    if (route) {
      Polyline2 line;
      for (const auto& s : route->samples()) {
        if (line.empty() || (s.position - line.back()).norm() > 1.0) line.push_back(s.position);
      }
      route_.addPolyline(line);
    }
    const RoadGraph graph = RoadGraph::fromPolylines(scene.roads);
    for (size_t i = 0; i < graph.nodes.size(); ++i) {
      if (graph.adjacency[i].size() != 2) junctions_.add(graph.nodes[i], graph.nodes[i]);
    }
    for (const auto& b : scene.world.buildings) {
      Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
      for (const auto& p : b.outline) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      boxes_.push_back({lo, hi});
    }
  }

  /// road_offset: minimal distance of every circle centre to any road centre line.
  bool free(const std::vector<Circle>& circles, double road_offset) const {
    for (const auto& c : circles) {
      if (junctions_.nearest(c.c, params_.junction_clearance) < kInf) return false;
      if (roads_.nearest(c.c, road_offset) < road_offset) return false;
      if (route_.nearest(c.c, params_.route_clearance + c.r) < kInf) return false;
      if (walls_.nearest(c.c, c.r + 0.3) < kInf) return false;
      for (size_t b = 0; b < boxes_.size(); ++b) {
        const auto& [lo, hi] = boxes_[b];
        if (c.c.x() < lo.x() || c.c.y() < lo.y() || c.c.x() > hi.x() || c.c.y() > hi.y()) continue;
        if (pointInPolygon(c.c, scene_.world.buildings[b].outline)) return false;
      }
      for (const auto& o : placed_) {
        if ((o.c - c.c).norm() < o.r + c.r + 0.2) return false;
      }
    }
    return true;
  }
  void place(const std::vector<Circle>& circles) {
    placed_.insert(placed_.end(), circles.begin(), circles.end());
  }

 private:
  const Scene& scene_;
  const ClutterParams& params_;
  SegmentHash walls_, roads_, route_{5.0}, junctions_;
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> boxes_;
  std::vector<Circle> placed_;  // few thousand at most; linear scan is fine
};

Primitive box(SimLabel label, const Eigen::Vector2d& c, double yaw, double half_len,
              double half_wid, double z0, double z1, float refl) {
  Primitive p;
  p.kind = Primitive::kBox;
  p.label = label;
  p.center = c;
  p.yaw = yaw;
  p.half_extent = Eigen::Vector2d(half_len, half_wid);
  p.z0 = z0;
  p.z1 = z1;
  p.reflectivity = refl;
  return p;
}

Polygon2 rectangle(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

}  // namespace

double buildingHeight(const OsmTags& tags, int64_t id, uint64_t seed) {
  auto number = [](const std::string& s, double& v) {
    char* end = nullptr;
    v = std::strtod(s.c_str(), &end);
    return end != s.c_str() && std::isfinite(v) && v > 0.0;
  };
  double v;
  auto it = tags.find("height");
  if (it != tags.end() && number(it->second, v)) return std::clamp(v, 2.5, 300.0);
  it = tags.find("building:levels");
  if (it != tags.end() && number(it->second, v)) return std::clamp(v * 3.0 + 1.0, 3.0, 300.0);
  SimRng rng(hashCombine(seed, uint64_t(id)));
  return rng.uniform(8.0, 25.0);
}

bool isDrivableHighway(const std::string& v) {
  static const std::set<std::string> kDrivable = {
      "motorway",      "trunk",       "primary",       "secondary",      "tertiary",
      "unclassified",  "residential", "living_street", "service",        "road",
      "motorway_link", "trunk_link",  "primary_link",  "secondary_link", "tertiary_link"};
  return kDrivable.count(v) > 0;
}

void settleBuildings(World& world) {
  for (auto& b : world.buildings) {
    double lo = kInf, hi = -kInf;
    for (const auto& p : b.outline) {
      const double z = world.ground.height(p.x(), p.y());
      lo = std::min(lo, z);
      hi = std::max(hi, z);
    }
    b.base_z = lo - 1.0;
    b.top_z = hi + b.height;
  }
}

Scene sceneFromOsm(const OsmData& osm, const EnuConverter& enu, uint64_t seed,
                   const GroundModel& ground) {
  Scene scene;
  scene.world.ground = ground;
  for (const Building& src : osm.buildings) {
    Building b = src;
    enu.project(b);
    if (b.outline_enu.size() < 3) continue;
    SimBuilding sb;
    sb.osm_id = b.id;
    sb.outline = b.outline_enu;
    sb.height = buildingHeight(b.tags, b.id, seed);
    sb.reflectivity = float(SimRng(hashCombine(seed ^ 0xb1d, uint64_t(b.id))).uniform(0.2, 0.5));
    scene.world.buildings.push_back(sb);
    scene.building_tags.push_back(b.tags);
  }
  settleBuildings(scene.world);
  for (const Road& src : osm.roads) {
    Road r = src;
    enu.project(r);
    if (r.nodes_enu.size() < 2) continue;
    Polyline2 line(r.nodes_enu.begin(), r.nodes_enu.end());
    if (isDrivableHighway(r.highway)) {
      scene.roads.push_back(line);
      scene.road_ids.push_back(r.id);
      scene.road_types.push_back(r.highway);
    } else {
      scene.other_roads.push_back(line);
      scene.other_road_ids.push_back(r.id);
      scene.other_road_types.push_back(r.highway);
    }
  }
  return scene;
}

Scene proceduralCity(const CityParams& params, const GroundModel& ground) {
  if (params.world == "forest" || params.world == "park") {
    ForestParams forest;
    forestPreset(params.world == "park" ? "park" : params.forest_density, forest);
    forest.seed = params.seed;
    return forestScene(forest, ground);
  }
  Scene scene;
  scene.world.ground = ground;
  SimRng rng(hashCombine(params.seed, 0x63697479ULL));
  std::vector<double> xs{0.0}, ys{0.0};
  for (int i = 0; i < params.blocks_x; ++i)
    xs.push_back(xs.back() + rng.uniform(params.block_min, params.block_max));
  for (int i = 0; i < params.blocks_y; ++i)
    ys.push_back(ys.back() + rng.uniform(params.block_min, params.block_max));
  // Centre the city on the ENU origin.
  const double cx = xs.back() / 2, cy = ys.back() / 2;
  for (auto& x : xs) x -= cx;
  for (auto& y : ys) y -= cy;
  int64_t road_id = 1;
  for (double x : xs) {
    Polyline2 line;
    for (double y : ys) line.emplace_back(x, y);
    scene.roads.push_back(line);
    scene.road_ids.push_back(road_id++);
    scene.road_types.push_back("residential");
  }
  for (double y : ys) {
    Polyline2 line;
    for (double x : xs) line.emplace_back(x, y);
    scene.roads.push_back(line);
    scene.road_ids.push_back(road_id++);
    scene.road_types.push_back("residential");
  }
  int64_t building_id = 1000;
  auto addBuilding = [&](Polygon2 outline, const std::string& shape) {
    SimBuilding b;
    b.osm_id = building_id++;
    b.outline = std::move(outline);
    b.height = rng.uniform(8.0, 25.0);
    b.reflectivity = float(rng.uniform(0.2, 0.5));
    scene.world.buildings.push_back(b);
    scene.building_tags.push_back({{"building", "yes"},
                                   {"height", std::to_string(int(std::round(b.height)))},
                                   {"sim:shape", shape}});
  };
  for (int bx = 0; bx < params.blocks_x; ++bx) {
    for (int by = 0; by < params.blocks_y; ++by) {
      const double x0 = xs[bx] + params.setback, x1 = xs[bx + 1] - params.setback;
      const double y0 = ys[by] + params.setback, y1 = ys[by + 1] - params.setback;
      if (x1 - x0 < 20 || y1 - y0 < 20 || rng.bernoulli(params.park_probability)) continue;
      // Two rows of lots along the longer side, each lot a building of varied shape.
      const bool along_x = (x1 - x0) >= (y1 - y0);
      const double len = along_x ? x1 - x0 : y1 - y0;
      const double depth = along_x ? y1 - y0 : x1 - x0;
      for (int row = 0; row < 2; ++row) {
        double u = 0.0;
        while (u < len - 10.0) {
          const double lot = std::min(rng.uniform(14.0, 30.0), len - u);
          if (lot < 10.0) break;
          const double gap = rng.uniform(0.0, 1.0) < 0.6 ? rng.uniform(1.0, 5.0) : 0.0;
          const double d0 = rng.uniform(0.0, 1.5),
                       d1 = std::min(depth / 2 - 1.5, rng.uniform(10.0, 20.0));
          // Lot rectangle in (along, across) coordinates, across measured from the street.
          double a0 = u + gap / 2, a1 = u + lot - gap / 2;
          double c0 = d0, c1 = d1;
          auto toXY = [&](double a, double c) {
            const double across = row == 0 ? c : depth - c;
            return along_x ? Eigen::Vector2d(x0 + a, y0 + across)
                           : Eigen::Vector2d(x0 + across, y0 + a);
          };
          const double shape = rng.uniform();
          Polygon2 poly;
          std::string kind;
          if (shape < params.round_probability) {
            const double r = std::min(a1 - a0, c1 - c0) / 2;
            const Eigen::Vector2d c = toXY((a0 + a1) / 2, (c0 + c1) / 2);
            const int n = 28;
            for (int k = 0; k < n; ++k) {
              const double ang = 2 * M_PI * k / n;
              poly.push_back(c + r * Eigen::Vector2d(std::cos(ang), std::sin(ang)));
            }
            kind = "round";
          } else if (shape < params.round_probability + params.l_shape_probability) {
            const double ca = a0 + rng.uniform(0.4, 0.6) * (a1 - a0);
            const double cc = c0 + rng.uniform(0.4, 0.6) * (c1 - c0);
            // L: full depth on [a0, ca], front part only on [ca, a1].
            poly = {toXY(a0, c0), toXY(a1, c0), toXY(a1, cc),
                    toXY(ca, cc), toXY(ca, c1), toXY(a0, c1)};
            kind = "l_shape";
          } else {
            poly = {toXY(a0, c0), toXY(a1, c0), toXY(a1, c1), toXY(a0, c1)};
            if (rng.bernoulli(0.2)) {  // slightly rotated
              Eigen::Vector2d c = Eigen::Vector2d::Zero();
              for (const auto& p : poly) c += p / 4.0;
              const double th = rng.uniform(-0.12, 0.12);
              const Eigen::Matrix2d R = Pose2(0, 0, th).rotation();
              const double shrink = 0.85;
              for (auto& p : poly) p = c + shrink * (R * (p - c));
            }
            kind = "rectangle";
          }
          addBuilding(poly, kind);
          u += lot;
        }
      }
    }
  }
  addDowntown(scene, params.downtown, params.seed, xs, ys);
  settleBuildings(scene.world);
  (void)rectangle;
  return scene;
}

void addClutter(Scene& scene, const ClutterParams& params, const Trajectory* route) {
  PlacementChecker checker(scene, route, params);
  World& world = scene.world;
  SimRng rng(hashCombine(params.seed, 0x636c7574ULL));
  auto gz = [&](const Eigen::Vector2d& p) { return world.ground.height(p.x(), p.y()); };

  for (const auto& road : scene.roads) {
    for (size_t i = 0; i + 1 < road.size(); ++i) {
      const Eigen::Vector2d a = road[i], b = road[i + 1];
      const double len = (b - a).norm();
      if (len < 1.0) continue;
      const Eigen::Vector2d dir = (b - a) / len, left(-dir.y(), dir.x());
      const double yaw = std::atan2(dir.y(), dir.x());
      for (int side = -1; side <= 1; side += 2) {
        // Trees: trunk + crown.
        for (double s = rng.uniform(0, params.tree_spacing); s < len;
             s += params.tree_spacing * rng.uniform(0.8, 1.3)) {
          if (!rng.bernoulli(params.tree_probability)) continue;
          const Eigen::Vector2d c =
              a + dir * s + left * side * (params.tree_offset + rng.uniform(-0.5, 0.5));
          const double crown = rng.uniform(1.5, 3.0), trunk_h = rng.uniform(2.2, 3.5);
          if (!checker.free({{c, crown}}, params.tree_offset - 0.8)) continue;
          checker.place({{c, crown}});
          Primitive trunk;
          trunk.kind = Primitive::kCylinder;
          trunk.label = SimLabel::kTree;
          trunk.center = c;
          trunk.radius = rng.uniform(0.15, 0.3);
          trunk.z0 = gz(c) - 0.5;
          trunk.z1 = gz(c) + trunk_h + crown * 0.5;
          trunk.reflectivity = 0.25f;
          Primitive top = trunk;
          top.kind = Primitive::kSphere;
          top.radius = crown;
          top.sphere_z = gz(c) + trunk_h + crown * 0.8;
          top.reflectivity = 0.35f;
          world.primitives.push_back(trunk);
          world.primitives.push_back(top);
        }
        // Street lamps.
        for (double s = rng.uniform(0, params.pole_spacing); s < len;
             s += params.pole_spacing * rng.uniform(0.9, 1.1)) {
          const Eigen::Vector2d c = a + dir * s + left * side * params.pole_offset;
          if (!checker.free({{c, 0.4}}, params.pole_offset - 0.5)) continue;
          checker.place({{c, 0.4}});
          Primitive pole;
          pole.kind = Primitive::kCylinder;
          pole.label = SimLabel::kPole;
          pole.center = c;
          pole.radius = 0.12;
          pole.z0 = gz(c) - 0.3;
          pole.z1 = gz(c) + rng.uniform(6.0, 8.0);
          pole.reflectivity = 0.6f;
          world.primitives.push_back(pole);
        }
        // Parked cars: body + cabin.
        for (double s = 3.0; s + 3.0 < len; s += params.car_slot) {
          if (!rng.bernoulli(params.car_probability)) continue;
          const double cyaw = yaw + rng.uniform(-0.05, 0.05);
          const Eigen::Vector2d c =
              a + dir * s + left * side * (params.car_offset + rng.uniform(-0.2, 0.2));
          const std::vector<Circle> fp = {{c - dir * 1.5, 0.95}, {c, 0.95}, {c + dir * 1.5, 0.95}};
          if (!checker.free(fp, params.car_offset - 0.5)) continue;
          checker.place(fp);
          const float refl = float(rng.uniform(0.15, 0.7));
          const double g = gz(c);
          world.primitives.push_back(
              box(SimLabel::kCar, c, cyaw, 2.2, 0.9, g + 0.25, g + 1.0, refl));
          world.primitives.push_back(
              box(SimLabel::kCar, c - dir * 0.3, cyaw, 1.2, 0.8, g + 1.0, g + 1.5, refl));
        }
        // Fences and low walls (at most fence_max_height).
        for (double s = 0.0; s + 6.0 < len; s += 25.0) {
          if (!rng.bernoulli(params.fence_probability)) continue;
          const double flen = std::min(rng.uniform(6.0, 20.0), len - s);
          const Eigen::Vector2d c = a + dir * (s + flen / 2) + left * side * params.fence_offset;
          const bool wall = rng.bernoulli(0.4);
          std::vector<Circle> fp;
          for (double t = -flen / 2; t <= flen / 2; t += 1.0) fp.push_back({c + dir * t, 0.3});
          if (!checker.free(fp, params.fence_offset - 0.8)) continue;
          checker.place(fp);
          const double g = gz(c);
          const double h = wall ? rng.uniform(0.6, 1.2) : rng.uniform(0.9, params.fence_max_height);
          world.primitives.push_back(box(SimLabel::kFence, c, yaw, flen / 2, wall ? 0.15 : 0.04,
                                         g - 0.5, g + h, wall ? 0.4f : 0.3f));
        }
      }
    }
  }
  // Moving objects on long road segments (cars in the opposite lane, pedestrians on sidewalks).
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> long_segments;
  for (const auto& road : scene.roads) {
    for (size_t i = 0; i + 1 < road.size(); ++i) {
      if ((road[i + 1] - road[i]).norm() > 40.0) long_segments.push_back({road[i], road[i + 1]});
    }
  }
  for (int k = 0; k < params.moving_cars + params.moving_pedestrians && !long_segments.empty();
       ++k) {
    const bool car = k < params.moving_cars;
    const auto& seg = long_segments[rng.uniformInt(0, int(long_segments.size()) - 1)];
    const Eigen::Vector2d dir = (seg.second - seg.first).normalized(), left(-dir.y(), dir.x());
    const double offset = car ? -2.4 : (rng.bernoulli(0.5) ? 5.2 : -5.2);
    const double trim = params.junction_clearance;
    MovingObject m;
    m.start = seg.first + dir * trim + left * offset;
    m.end = seg.second - dir * trim + left * offset;
    m.speed = car ? rng.uniform(4.0, 9.0) : rng.uniform(1.0, 1.6);
    m.phase = rng.uniform(0.0, 100.0);
    m.shape = car ? box(SimLabel::kMoving, Eigen::Vector2d::Zero(), 0, 2.2, 0.9, 0.25, 1.5, 0.5f)
                  : box(SimLabel::kMoving, Eigen::Vector2d::Zero(), 0, 0.3, 0.3, 0.0, 1.75, 0.3f);
    world.moving.push_back(m);
  }
}

}  // namespace osm_graph_slam::sim
