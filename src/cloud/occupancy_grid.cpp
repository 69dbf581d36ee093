#include "osm_graph_slam/cloud/occupancy_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_set>

#include "osm_graph_slam/common/cell_key.h"

namespace osm_graph_slam {
namespace {

constexpr int kTileBits = 5;
constexpr int64_t kTileSize = int64_t{1} << kTileBits;  ///< cells per tile side
/// Log-odds are summed as integers of this many units per nat: adding and later subtracting a
/// keyframe's contribution then gives back exactly the sums before it.
constexpr double kLogOddsScale = 1000.0;
/// Radius of the heights that give a keyframe's ground without a floor plane [m]: near enough
/// that the road dominates them, far enough to hold a few hundred returns.
constexpr double kGroundRadius = 15.0;

int32_t fixedLogOdds(double probability) {
  return static_cast<int32_t>(
      std::lround(std::log(probability / (1.0 - probability)) * kLogOddsScale));
}

int64_t floorDiv(int64_t a, int64_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

bool finitePositive(double v) {
  return std::isfinite(v) && v > 0.0;
}
bool probability(double v) {
  return std::isfinite(v) && v > 0.0 && v < 1.0;
}

/// The height of the ground under (x, y) before the local correction.
class GroundModel {
 public:
  GroundModel(const PointCloud& cloud, const Eigen::Vector3f& origin,
              const std::optional<Eigen::Vector4d>& floor, const OccupancyGridParams& p) {
    // A plane steeper than 60 degrees is no ground (the detector's own limit is far lower).
    if (floor && floor->allFinite() && std::abs((*floor)(2)) > 0.5 * floor->head<3>().norm()) {
      plane_ = *floor;
      return;
    }
    std::vector<float> heights;
    for (const auto& pt : cloud) {
      const double r = std::hypot(pt.x - origin.x(), pt.y - origin.y());
      if (std::isfinite(pt.z) && r >= p.min_range && r <= kGroundRadius) heights.push_back(pt.z);
    }
    if (heights.empty())
      for (const auto& pt : cloud)
        if (std::isfinite(pt.z)) heights.push_back(pt.z);
    if (heights.empty()) return;
    const size_t k =
        std::min(heights.size() - 1, static_cast<size_t>(p.ground_percentile * heights.size()));
    std::nth_element(heights.begin(), heights.begin() + k, heights.end());
    flat_ = heights[k];
  }
  double at(double x, double y) const {
    if (plane_) return -((*plane_)(0) * x + (*plane_)(1) * y + (*plane_)(3)) / (*plane_)(2);
    return flat_;
  }

 private:
  std::optional<Eigen::Vector4d> plane_;
  double flat_ = 0.0;
};

/// The lowest point per ground_cell around the sensor: the local correction of the ground model.
class LowestPoints {
 public:
  LowestPoints(const Eigen::Vector3f& origin, const OccupancyGridParams& p)
      : origin_(origin), cell_(p.ground_cell), half_(p.max_range) {
    side_ = static_cast<int>(std::ceil(2.0 * half_ / cell_)) + 1;
    lowest_.assign(static_cast<size_t>(side_) * side_, std::numeric_limits<float>::infinity());
  }
  float& at(float x, float y) { return lowest_[index(x, y)]; }
  float at(float x, float y) const { return lowest_[index(x, y)]; }

 private:
  size_t index(float x, float y) const {
    const int ix = std::clamp(static_cast<int>((x - origin_.x() + half_) / cell_), 0, side_ - 1);
    const int iy = std::clamp(static_cast<int>((y - origin_.y() + half_) / cell_), 0, side_ - 1);
    return static_cast<size_t>(iy) * side_ + ix;
  }
  Eigen::Vector3f origin_;
  double cell_, half_;
  int side_ = 0;
  std::vector<float> lowest_;
};

/// Per azimuth sector: the nearest obstacle and the farthest ground return.
struct Sector {
  float hit_range = std::numeric_limits<float>::infinity();
  float ground_range = -1.0f;
  Eigen::Vector3f hit, ground;
};

}  // namespace

std::string occupancyGridParamsError(const OccupancyGridParams& p) {
  if (!finitePositive(p.resolution)) return "grid_resolution must be a finite number > 0";
  if (!std::isfinite(p.min_height) || !std::isfinite(p.max_height) || p.min_height >= p.max_height)
    return "grid_min_height must be below grid_max_height (both finite)";
  if (!std::isfinite(p.min_range) || p.min_range < 0.0 || !finitePositive(p.max_range) ||
      p.min_range >= p.max_range)
    return "grid_min_range must be >= 0 and below grid_max_range";
  if (p.max_range / p.resolution > 1e5)
    return "grid_max_range / grid_resolution is above 1e5 cells per ray";
  if (!std::isfinite(p.azimuth_step_deg) || p.azimuth_step_deg < 0.01 || p.azimuth_step_deg > 45.0)
    return "grid_azimuth_step_deg must be in [0.01, 45]";
  if (!probability(p.hit_probability) || p.hit_probability <= 0.5)
    return "grid_hit_probability must be in (0.5, 1)";
  if (!probability(p.miss_probability) || p.miss_probability >= 0.5)
    return "grid_miss_probability must be in (0, 0.5)";
  if (!probability(p.min_probability) || !probability(p.max_probability) ||
      p.min_probability >= p.max_probability)
    return "grid_min_probability must be below grid_max_probability, both in (0, 1)";
  if (!std::isfinite(p.ground_percentile) || p.ground_percentile < 0.0 || p.ground_percentile > 1.0)
    return "grid_ground_percentile must be in [0, 1]";
  if (!finitePositive(p.ground_cell) || p.max_range / p.ground_cell > 1000.0)
    return "grid_ground_cell must be > 0 and at least grid_max_range / 1000";
  if (!std::isfinite(p.ground_tolerance) || p.ground_tolerance < 0.0)
    return "grid_ground_tolerance must be >= 0";
  if (!std::isfinite(p.move_translation) || p.move_translation < 0.0 ||
      !std::isfinite(p.move_rotation) || p.move_rotation < 0.0)
    return "grid_move_translation and grid_move_rotation must be >= 0";
  return {};
}

PlanarScan extractPlanarScan(const PointCloud& cloud, const Eigen::Vector3f& sensor_origin,
                             const std::optional<Eigen::Vector4d>& floor,
                             const OccupancyGridParams& p) {
  PlanarScan scan;
  scan.origin = sensor_origin;
  const GroundModel ground(cloud, sensor_origin, floor, p);
  LowestPoints lowest(sensor_origin, p);
  auto inRange = [&](const PointT& pt, float* range) {
    *range = std::hypot(pt.x - sensor_origin.x(), pt.y - sensor_origin.y());
    return std::isfinite(pt.z) && *range >= p.min_range && *range <= p.max_range;
  };
  float range = 0.0f;
  for (const auto& pt : cloud)
    if (inRange(pt, &range)) lowest.at(pt.x, pt.y) = std::min(lowest.at(pt.x, pt.y), pt.z);

  const double step = p.azimuth_step_deg * M_PI / 180.0;
  std::vector<Sector> sectors(static_cast<size_t>(std::ceil(2.0 * M_PI / step)));
  std::unordered_set<int64_t> hit_cells;
  for (const auto& pt : cloud) {
    if (!inRange(pt, &range)) continue;
    const double base = ground.at(pt.x, pt.y);
    const double local = std::clamp<double>(lowest.at(pt.x, pt.y), base - p.ground_tolerance,
                                            base + p.ground_tolerance);
    const double height = pt.z - local;
    if (height > p.max_height) continue;  // overhangs: the vehicle passes under them
    const double azimuth = std::atan2(pt.y - sensor_origin.y(), pt.x - sensor_origin.x()) + M_PI;
    Sector& s = sectors[std::min(sectors.size() - 1, static_cast<size_t>(azimuth / step))];
    const Eigen::Vector3f point(pt.x, pt.y, pt.z);
    if (height < p.min_height) {
      if (range > s.ground_range) s.ground_range = range, s.ground = point;
      continue;
    }
    if (range < s.hit_range) s.hit_range = range, s.hit = point;
    const int64_t key = packCellKey(static_cast<int64_t>(std::floor(pt.x / p.resolution)),
                                    static_cast<int64_t>(std::floor(pt.y / p.resolution)));
    if (hit_cells.insert(key).second) scan.hits.push_back(point);
  }
  for (const Sector& s : sectors) {
    if (std::isfinite(s.hit_range)) {
      scan.ray_ends.push_back(s.hit);
      scan.ray_end_is_hit.push_back(1);
    } else if (s.ground_range >= 0.0f) {
      scan.ray_ends.push_back(s.ground);
      scan.ray_end_is_hit.push_back(0);
    }
  }
  return scan;
}

struct OccupancyGrid::Tile {
  static constexpr size_t kCells = static_cast<size_t>(kTileSize * kTileSize);
  int32_t sum[kCells] = {};           ///< log-odds, fixed point
  int32_t observations[kCells] = {};  ///< keyframes that hit or crossed the cell
  uint32_t stamp[kCells] = {};        ///< the last render that counted the cell
  uint32_t hit_stamp[kCells] = {};    ///< the last render that saw an obstacle in it
};

OccupancyGrid::OccupancyGrid(const OccupancyGridParams& params) : params_(params) {
  const std::string error = occupancyGridParamsError(params);
  if (!error.empty()) throw std::invalid_argument("occupancy grid: " + error);
  hit_update_ = fixedLogOdds(params.hit_probability);
  miss_update_ = fixedLogOdds(params.miss_probability);
  min_sum_ = fixedLogOdds(params.min_probability);
  max_sum_ = fixedLogOdds(params.max_probability);
}

OccupancyGrid::~OccupancyGrid() = default;
OccupancyGrid::OccupancyGrid(OccupancyGrid&&) noexcept = default;
OccupancyGrid& OccupancyGrid::operator=(OccupancyGrid&&) noexcept = default;

void OccupancyGrid::insertKeyframe(uint64_t id, const Eigen::Isometry3d& pose,
                                   const PointCloud& cloud,
                                   const std::optional<Eigen::Vector4d>& floor,
                                   const Eigen::Vector3f& sensor_origin) {
  insertScan(id, pose, extractPlanarScan(cloud, sensor_origin, floor, params_));
}

void OccupancyGrid::insertScan(uint64_t id, const Eigen::Isometry3d& pose, PlanarScan scan) {
  const auto old = keyframes_.find(id);
  if (old != keyframes_.end()) {
    render(old->second, -1);
    keyframes_.erase(old);
  }
  const KeptKeyframe& kept = keyframes_[id] = KeptKeyframe{pose, std::move(scan)};
  render(kept, +1);
}

bool OccupancyGrid::moved(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to) const {
  const Eigen::Isometry3d delta = from.inverse() * to;
  return delta.translation().norm() > params_.move_translation ||
         Eigen::AngleAxisd(delta.linear()).angle() > params_.move_rotation;
}

size_t OccupancyGrid::updatePoses(const std::map<uint64_t, Eigen::Isometry3d>& poses) {
  size_t count = 0;
  for (const auto& [id, pose] : poses) {
    const auto it = keyframes_.find(id);
    if (it == keyframes_.end() || !moved(it->second.pose, pose)) continue;
    render(it->second, -1);
    it->second.pose = pose;
    render(it->second, +1);
    ++count;
  }
  return count;
}

void OccupancyGrid::rerender() {
  tiles_.clear();
  last_tile_ = nullptr;
  for (const auto& [id, kf] : keyframes_) render(kf, +1);
}

OccupancyGrid::Tile& OccupancyGrid::tileAt(int64_t tx, int64_t ty) {
  const int64_t key = packCellKey(tx, ty);
  if (last_tile_ && key == last_tile_key_) return *last_tile_;  // rays stay in a tile for long
  std::unique_ptr<Tile>& tile = tiles_[key];
  if (!tile) tile = std::make_unique<Tile>();
  last_tile_key_ = key;
  last_tile_ = tile.get();
  return *tile;
}

OccupancyGrid::Tile& OccupancyGrid::cell(int64_t cx, int64_t cy, size_t* index) {
  const int64_t tx = floorDiv(cx, kTileSize), ty = floorDiv(cy, kTileSize);
  *index = static_cast<size_t>((cy - ty * kTileSize) * kTileSize + (cx - tx * kTileSize));
  return tileAt(tx, ty);
}

bool OccupancyGrid::besideHit(int64_t cx, int64_t cy, uint32_t stamp) {
  size_t i = 0;
  const Tile& tile = cell(cx, cy, &i);
  const int64_t lx = static_cast<int64_t>(i) % kTileSize, ly = static_cast<int64_t>(i) / kTileSize;
  if (lx > 0 && lx + 1 < kTileSize && ly > 0 && ly + 1 < kTileSize)  // all four in this tile
    return tile.hit_stamp[i - 1] == stamp || tile.hit_stamp[i + 1] == stamp ||
           tile.hit_stamp[i - kTileSize] == stamp || tile.hit_stamp[i + kTileSize] == stamp;
  static constexpr int kSides[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (const auto& d : kSides)
    if (cell(cx + d[0], cy + d[1], &i).hit_stamp[i] == stamp) return true;
  return false;
}

void OccupancyGrid::addEvidence(int64_t cx, int64_t cy, bool hit, uint32_t stamp, int sign) {
  size_t i = 0;
  Tile& tile = cell(cx, cy, &i);
  if (tile.stamp[i] == stamp) return;  // this keyframe counted the cell already
  tile.stamp[i] = stamp;
  // A ray grazing a corner the keyframe sees would free a cell inside the building: cells beside
  // the keyframe's own obstacles are not free for it (hits are rendered before rays).
  if (!hit && besideHit(cx, cy, stamp)) return;
  if (hit) tile.hit_stamp[i] = stamp;
  tile.sum[i] += sign * (hit ? hit_update_ : miss_update_);
  tile.observations[i] += sign;
}

// Amanatides-Woo cell walk from one point to another.
void OccupancyGrid::traceFree(const Eigen::Vector2d& from, const Eigen::Vector2d& to,
                              bool include_end, uint32_t stamp, int sign) {
  const Eigen::Vector2d a = from / params_.resolution, b = to / params_.resolution;
  int64_t cx = static_cast<int64_t>(std::floor(a.x())),
          cy = static_cast<int64_t>(std::floor(a.y()));
  const int64_t ex = static_cast<int64_t>(std::floor(b.x())),
                ey = static_cast<int64_t>(std::floor(b.y()));
  const Eigen::Vector2d d = b - a;
  const int step_x = d.x() > 0 ? 1 : -1, step_y = d.y() > 0 ? 1 : -1;
  const double inf = std::numeric_limits<double>::infinity();
  const double delta_x = d.x() != 0.0 ? 1.0 / std::abs(d.x()) : inf;
  const double delta_y = d.y() != 0.0 ? 1.0 / std::abs(d.y()) : inf;
  double next_x = d.x() != 0.0 ? (step_x > 0 ? cx + 1 - a.x() : a.x() - cx) * delta_x : inf;
  double next_y = d.y() != 0.0 ? (step_y > 0 ? cy + 1 - a.y() : a.y() - cy) * delta_y : inf;
  const int64_t steps = std::abs(ex - cx) + std::abs(ey - cy);
  for (int64_t n = 0; n <= steps; ++n) {
    if (cx == ex && cy == ey) break;
    addEvidence(cx, cy, false, stamp, sign);
    if (next_x < next_y) {
      cx += step_x;
      next_x += delta_x;
    } else {
      cy += step_y;
      next_y += delta_y;
    }
  }
  if (include_end) addEvidence(ex, ey, false, stamp, sign);
}

void OccupancyGrid::render(const KeptKeyframe& kf, int sign) {
  const uint32_t stamp = ++render_count_;
  const double res = params_.resolution;
  auto cellOf = [&](const Eigen::Vector3f& p, int64_t* cx, int64_t* cy) {
    const Eigen::Vector3d m = kf.pose * p.cast<double>();
    *cx = static_cast<int64_t>(std::floor(m.x() / res));
    *cy = static_cast<int64_t>(std::floor(m.y() / res));
  };
  int64_t cx = 0, cy = 0;
  // Hits before rays: a cell this keyframe sees as an obstacle is not also free for it.
  for (const Eigen::Vector3f& hit : kf.scan.hits) {
    cellOf(hit, &cx, &cy);
    addEvidence(cx, cy, true, stamp, sign);
  }
  for (size_t i = 0; i < kf.scan.ray_ends.size(); ++i) {
    if (!kf.scan.ray_end_is_hit[i]) continue;
    cellOf(kf.scan.ray_ends[i], &cx, &cy);
    addEvidence(cx, cy, true, stamp, sign);
  }
  const Eigen::Vector2d origin = (kf.pose * kf.scan.origin.cast<double>()).head<2>();
  for (size_t i = 0; i < kf.scan.ray_ends.size(); ++i) {
    const Eigen::Vector2d end = (kf.pose * kf.scan.ray_ends[i].cast<double>()).head<2>();
    traceFree(origin, end, !kf.scan.ray_end_is_hit[i], stamp, sign);
  }
}

OccupancyGridImage OccupancyGrid::image() const {
  OccupancyGridImage out;
  out.resolution = params_.resolution;
  if (tiles_.empty()) return out;
  int64_t min_tx = std::numeric_limits<int64_t>::max(), min_ty = min_tx;
  int64_t max_tx = std::numeric_limits<int64_t>::min(), max_ty = max_tx;
  for (const auto& [key, tile] : tiles_) {
    const int64_t tx = static_cast<int32_t>(static_cast<uint64_t>(key) >> 32);
    const int64_t ty = static_cast<int32_t>(static_cast<uint64_t>(key) & 0xffffffffu);
    min_tx = std::min(min_tx, tx), max_tx = std::max(max_tx, tx);
    min_ty = std::min(min_ty, ty), max_ty = std::max(max_ty, ty);
  }
  out.width = static_cast<int>((max_tx - min_tx + 1) * kTileSize);
  out.height = static_cast<int>((max_ty - min_ty + 1) * kTileSize);
  out.origin = Eigen::Vector2d(min_tx, min_ty) * (kTileSize * params_.resolution);
  out.cells.assign(static_cast<size_t>(out.width) * out.height, -1);
  for (const auto& [key, tile] : tiles_) {
    const int64_t tx = static_cast<int32_t>(static_cast<uint64_t>(key) >> 32);
    const int64_t ty = static_cast<int32_t>(static_cast<uint64_t>(key) & 0xffffffffu);
    for (int64_t j = 0; j < kTileSize; ++j)
      for (int64_t i = 0; i < kTileSize; ++i) {
        const size_t c = static_cast<size_t>(j * kTileSize + i);
        if (tile->observations[c] <= 0) continue;
        const double logit = std::clamp(tile->sum[c], min_sum_, max_sum_) / kLogOddsScale;
        const int64_t x = (tx - min_tx) * kTileSize + i, y = (ty - min_ty) * kTileSize + j;
        out.cells[static_cast<size_t>(y) * out.width + x] =
            static_cast<int8_t>(std::lround(100.0 / (1.0 + std::exp(-logit))));
      }
  }
  return out;
}

}  // namespace osm_graph_slam
