#include "downtown.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

constexpr uint64_t kDowntownTag = 0x646f776e746f776eULL;  // "downtown"
/// Tower ids start far above the city's (1000 + a few hundred) so that none collides.
constexpr int64_t kFirstTowerId = 5000000;

/// The district's blocks: columns [x0, x1) and rows [y0, y1) of the grid, centred.
struct BlockRange {
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
};

BlockRange centralBlocks(const DowntownParams& p, int blocks_x, int blocks_y) {
  const int nx = std::clamp(p.blocks_x, 1, blocks_x), ny = std::clamp(p.blocks_y, 1, blocks_y);
  const int x0 = (blocks_x - nx) / 2, y0 = (blocks_y - ny) / 2;
  return {x0, x0 + nx, y0, y0 + ny};
}

/// Street lines lines[first..last] (inclusive) and a street through the middle of each block.
std::vector<double> withMidStreets(const std::vector<double>& lines, int first, int last) {
  std::vector<double> out;
  for (int i = first; i <= last; ++i) {
    out.push_back(lines[size_t(i)]);
    if (i < last) out.push_back(0.5 * (lines[size_t(i)] + lines[size_t(i) + 1]));
  }
  return out;
}

/// lines with the extra coordinates inserted, sorted (the junctions of a road).
std::vector<double> mergedSorted(std::vector<double> lines, const std::vector<double>& extra) {
  lines.insert(lines.end(), extra.begin(), extra.end());
  std::sort(lines.begin(), lines.end());
  lines.erase(std::unique(lines.begin(), lines.end()), lines.end());
  return lines;
}

Polyline2 northSouthRoad(double x, const std::vector<double>& ys) {
  Polyline2 line;
  for (double y : ys) line.emplace_back(x, y);
  return line;
}

Polyline2 eastWestRoad(double y, const std::vector<double>& xs) {
  Polyline2 line;
  for (double x : xs) line.emplace_back(x, y);
  return line;
}

void addRoad(Scene& scene, Polyline2 line) {
  const int64_t id = scene.road_ids.empty()
                         ? 1
                         : *std::max_element(scene.road_ids.begin(), scene.road_ids.end()) + 1;
  scene.roads.push_back(std::move(line));
  scene.road_ids.push_back(id);
  scene.road_types.push_back("residential");
}

/// The new streets, and a vertex in every old road where one meets it (road graph nodes merge
/// only at shared vertices).
void addNarrowStreets(Scene& scene, const BlockRange& d, const std::vector<double>& xs,
                      const std::vector<double>& ys) {
  const std::vector<double> dx = withMidStreets(xs, d.x0, d.x1);
  const std::vector<double> dy = withMidStreets(ys, d.y0, d.y1);
  for (int i = d.x0; i <= d.x1; ++i)
    scene.roads[size_t(i)] = northSouthRoad(xs[size_t(i)], mergedSorted(ys, dy));
  for (int j = d.y0; j <= d.y1; ++j)
    scene.roads[xs.size() + size_t(j)] = eastWestRoad(ys[size_t(j)], mergedSorted(xs, dx));
  for (size_t i = 1; i < dx.size(); i += 2) addRoad(scene, northSouthRoad(dx[i], dy));
  for (size_t j = 1; j < dy.size(); j += 2) addRoad(scene, eastWestRoad(dy[j], dx));
}

Eigen::Vector2d vertexMean(const Polygon2& outline) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const auto& p : outline) sum += p;
  return sum / double(std::max<size_t>(outline.size(), 1));
}

void removeBuildingsInside(Scene& scene, const Eigen::AlignedBox2d& box) {
  size_t kept = 0;
  for (size_t i = 0; i < scene.world.buildings.size(); ++i) {
    if (box.contains(vertexMean(scene.world.buildings[i].outline))) continue;
    scene.world.buildings[kept] = scene.world.buildings[i];
    scene.building_tags[kept] = scene.building_tags[i];
    ++kept;
  }
  scene.world.buildings.resize(kept);
  scene.building_tags.resize(kept);
}

void addTower(Scene& scene, Polygon2 outline, double height, float reflectivity, int64_t id) {
  SimBuilding b;
  b.osm_id = id;
  b.outline = std::move(outline);
  b.height = height;
  b.reflectivity = reflectivity;
  scene.world.buildings.push_back(b);
  scene.building_tags.push_back({{"building", "yes"},
                                 {"height", std::to_string(int(std::round(height)))},
                                 {"sim:shape", "tower"},
                                 {"sim:district", "downtown"}});
}

/// A quarter block (street lines lo..hi) built up to the setback: two rows of towers back to
/// back along the longer side, frontages lot_min..lot_max, now and then a narrow passage.
void fillQuarterBlock(Scene& scene, const DowntownParams& p, const Eigen::Vector2d& lo,
                      const Eigen::Vector2d& hi, SimRng& rng, int64_t& next_id) {
  const Eigen::Vector2d a = lo.array() + p.setback, b = hi.array() - p.setback;
  if ((b - a).minCoeff() < 8.0) return;
  const bool along_x = (b.x() - a.x()) >= (b.y() - a.y());
  const double length = along_x ? b.x() - a.x() : b.y() - a.y();
  const double half_depth = 0.5 * (along_x ? b.y() - a.y() : b.x() - a.x());
  auto corner = [&](double along, double across) {
    return along_x ? Eigen::Vector2d(a.x() + along, a.y() + across)
                   : Eigen::Vector2d(a.x() + across, a.y() + along);
  };
  for (int row = 0; row < 2; ++row) {
    const double c0 = row * half_depth, c1 = c0 + half_depth;
    for (double u = 0.0; u < length - 1e-6;) {
      double lot = rng.uniform(p.lot_min, p.lot_max);
      if (length - u - lot < p.lot_min) lot = length - u;  // no sliver at the corner
      const double gap = rng.bernoulli(p.gap_probability) ? rng.uniform(1.0, 3.0) : 0.0;
      const double a0 = u + gap / 2, a1 = u + lot - gap / 2;
      addTower(scene, {corner(a0, c0), corner(a1, c0), corner(a1, c1), corner(a0, c1)},
               rng.uniform(p.min_height, p.max_height), float(rng.uniform(0.2, 0.5)), next_id++);
      u += lot;
    }
  }
}

}  // namespace

void addDowntown(Scene& scene, const DowntownParams& params, uint64_t seed,
                 const std::vector<double>& xs, const std::vector<double>& ys) {
  if (!params.enabled || xs.size() < 2 || ys.size() < 2) return;
  const BlockRange d = centralBlocks(params, int(xs.size()) - 1, int(ys.size()) - 1);
  scene.downtown = Eigen::AlignedBox2d(Eigen::Vector2d(xs[size_t(d.x0)], ys[size_t(d.y0)]),
                                       Eigen::Vector2d(xs[size_t(d.x1)], ys[size_t(d.y1)]));
  removeBuildingsInside(scene, scene.downtown);
  addNarrowStreets(scene, d, xs, ys);
  const std::vector<double> dx = withMidStreets(xs, d.x0, d.x1);
  const std::vector<double> dy = withMidStreets(ys, d.y0, d.y1);
  SimRng rng(hashCombine(seed, kDowntownTag));
  int64_t next_id = kFirstTowerId;
  for (size_t i = 0; i + 1 < dx.size(); ++i)
    for (size_t j = 0; j + 1 < dy.size(); ++j)
      fillQuarterBlock(scene, params, Eigen::Vector2d(dx[i], dy[j]),
                       Eigen::Vector2d(dx[i + 1], dy[j + 1]), rng, next_id);
}

}  // namespace osm_graph_slam::sim
