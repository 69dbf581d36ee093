#pragma once
// A 2-D occupancy grid from keyframe clouds at their optimised poses, for planners (move_base)
// and map_server. Each keyframe is reduced once to a small planar scan in its own frame (obstacle
// cells in a height band above the local ground, one free-space ray per azimuth sector); the grid
// sums the scans' log-odds at the keyframes' current poses. Sums are clamped only when read, so a
// keyframe the graph moves is taken out at its old pose and added at its new one exactly, in
// O(its scan), and the whole grid can be re-rendered from the kept scans.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "osm_graph_slam/cloud/occupancy_grid_params.h"
#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// A keyframe's contribution in its own frame: what the grid keeps per keyframe.
struct PlanarScan {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();  ///< the sensor
  std::vector<Eigen::Vector3f> hits;                 ///< one per obstacle cell
  std::vector<Eigen::Vector3f> ray_ends;             ///< one per azimuth sector
  std::vector<uint8_t> ray_end_is_hit;               ///< per ray end: free up to it, or in it too
};

/// The grid as nav_msgs/OccupancyGrid holds it: row-major, row 0 at the lowest y, -1 unknown,
/// else 0..100 (the clamped probability in percent).
struct OccupancyGridImage {
  double resolution = 0.0;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  ///< map position of cell (0, 0)'s corner
  int width = 0, height = 0;
  std::vector<int8_t> cells;
  int8_t at(int x, int y) const { return cells[static_cast<size_t>(y) * width + x]; }
};

/// Keyframe-local ground and obstacle extraction (the part of insertKeyframe that reads points).
/// `floor`: a x + b y + c z + d = 0 in the cloud's frame, when the keyframe has one.
PlanarScan extractPlanarScan(const PointCloud& cloud, const Eigen::Vector3f& sensor_origin,
                             const std::optional<Eigen::Vector4d>& floor,
                             const OccupancyGridParams& params);

class OccupancyGrid {
 public:
  /// Throws std::invalid_argument naming the bad key (occupancyGridParamsError).
  explicit OccupancyGrid(const OccupancyGridParams& params = {});
  ~OccupancyGrid();
  OccupancyGrid(OccupancyGrid&&) noexcept;
  OccupancyGrid& operator=(OccupancyGrid&&) noexcept;

  /// Adds a keyframe (pose: map <- keyframe); a known id is replaced. O(points + rays).
  void insertKeyframe(uint64_t id, const Eigen::Isometry3d& pose, const PointCloud& cloud,
                      const std::optional<Eigen::Vector4d>& floor = std::nullopt,
                      const Eigen::Vector3f& sensor_origin = Eigen::Vector3f::Zero());
  void insertScan(uint64_t id, const Eigen::Isometry3d& pose, PlanarScan scan);
  /// New poses of known keyframes (others are ignored); re-renders those that moved more than
  /// move_translation / move_rotation. Returns how many did.
  size_t updatePoses(const std::map<uint64_t, Eigen::Isometry3d>& poses);
  /// Clears the cells and renders every kept scan again at its current pose.
  void rerender();

  bool contains(uint64_t id) const { return keyframes_.count(id) > 0; }
  size_t numKeyframes() const { return keyframes_.size(); }
  /// Every observed cell, in the smallest box of whole tiles holding them.
  OccupancyGridImage image() const;
  const OccupancyGridParams& params() const { return params_; }

 private:
  struct Tile;
  struct KeptKeyframe {
    Eigen::Isometry3d pose;
    PlanarScan scan;
  };
  Tile& tileAt(int64_t tx, int64_t ty);
  Tile& cell(int64_t cx, int64_t cy, size_t* index);
  bool besideHit(int64_t cx, int64_t cy, uint32_t stamp);
  void render(const KeptKeyframe& kf, int sign);
  void traceFree(const Eigen::Vector2d& from, const Eigen::Vector2d& to, bool include_end,
                 uint32_t stamp, int sign);
  void addEvidence(int64_t cx, int64_t cy, bool hit, uint32_t stamp, int sign);
  bool moved(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to) const;

  OccupancyGridParams params_;
  int32_t hit_update_ = 0, miss_update_ = 0;  ///< log-odds in fixed point (exact sums)
  int32_t min_sum_ = 0, max_sum_ = 0;         ///< clamping bounds in the same units
  std::unordered_map<int64_t, std::unique_ptr<Tile>> tiles_;
  std::map<uint64_t, KeptKeyframe> keyframes_;
  int64_t last_tile_key_ = 0;
  Tile* last_tile_ =
      nullptr;  ///< the tile of the last cell (tiles are never freed but by rerender)
  uint32_t render_count_ = 0;  ///< stamps a render's cells: one hit or miss per keyframe per cell
};

}  // namespace osm_graph_slam
