#pragma once
// Exhaustive correlative search of a planar pose (x, y, yaw) in bird's-eye view, after the idea
// of real-time correlative scan matching (Olson, ICRA 2009): the target's structure above the
// ground becomes a likelihood field on a 2D grid, the query's structure a thinned set of 2D
// points, and every pose of a search window on a lattice is scored by the mean field value under
// the transformed query points. Because the whole window is scored, the result carries its
// runner-up: the best local maximum at least peak_separation away from the best pose. A runner-up
// that scores almost as well as the best means the scans do not decide between two placements
// (repetitive facades, a street that constrains only one direction): the match is ambiguous.
#include <Eigen/Core>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct BevCorrelationParams {
  double cell_size = 0.5;            ///< [m] field resolution = translation step
  double sigma = 0.5;                ///< [m] width of a structure point's likelihood
  double max_range = 40.0;           ///< [m] query points farther from the sensor are ignored
  double query_point_spacing = 1.0;  ///< [m] 2D thinning of the query points
  double yaw_step = 0.035;           ///< [rad] (2 deg: 0.5 m at 30 m range, one field cell)
  double min_height = 0.3;           ///< [m] above ground: lower points are ground
  double max_height = 30.0;          ///< [m] above ground
  double sensor_height = 1.73;       ///< [m] sensor above ground (cloud z + this = height)
  double peak_separation = 2.0;      ///< [m] distinct placements are at least this far apart
};

/// Where to search: translation disc around center (x, y) and yaw interval around center yaw.
struct BevSearchWindow {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< x, y [m], yaw [rad]
  double translation_radius = 4.0;                   ///< [m]
  double yaw_radius = 0.1;                           ///< [rad]
};

struct BevSearchResult {
  bool valid = false;  ///< false: too few query points or an empty target
  Eigen::Vector3d best = Eigen::Vector3d::Zero();  ///< x, y, yaw of the best pose
  double best_score = 0.0;                         ///< mean likelihood in [0, 1]
  /// Best local maximum at least peak_separation from best (score 0 and valid_runner_up false
  /// when the window holds none).
  Eigen::Vector3d runner_up = Eigen::Vector3d::Zero();
  double runner_up_score = 0.0;
  bool valid_runner_up = false;
  int poses = 0;         ///< poses scored
  int query_points = 0;  ///< thinned query points used
  /// runner-up / best score: 1 = two placements fit equally well, 0 = unique.
  double ambiguity() const { return best_score > 0.0 ? runner_up_score / best_score : 1.0; }
};

/// The target's structure as a likelihood field: each cell holds exp(-d^2 / 2 sigma^2) of the
/// distance from its centre to the nearest occupied cell's centre (cut at 3 sigma).
class BevLikelihoodField {
 public:
  BevLikelihoodField() = default;
  BevLikelihoodField(const PointCloud& cloud, const BevCorrelationParams& params);

  bool empty() const { return occupied_ == 0; }
  int width() const { return width_; }
  int height() const { return height_; }
  double cellSize() const { return cell_; }
  const Eigen::Vector2d& origin() const { return origin_; }
  /// Field value at a cell (0 outside).
  float at(int ix, int iy) const {
    return (ix < 0 || iy < 0 || ix >= width_ || iy >= height_) ? 0.f : values_[iy * width_ + ix];
  }
  const std::vector<float>& values() const { return values_; }
  int occupiedCells() const { return occupied_; }

 private:
  double cell_ = 0.5;
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();  ///< world position of cell (0, 0)'s corner
  int width_ = 0, height_ = 0, occupied_ = 0;
  std::vector<float> values_;
};

/// Structure points above the ground within max_range, thinned to one per spacing^2 cell
/// (the mean of the cell's points).
std::vector<Eigen::Vector2f> bevQueryPoints(const PointCloud& cloud,
                                            const BevCorrelationParams& params);

/// Scores every pose of the window (translation lattice cell_size inside the disc, yaw lattice
/// yaw_step) and returns the best pose and the runner-up placement.
BevSearchResult searchBev(const BevLikelihoodField& field,
                          const std::vector<Eigen::Vector2f>& query_points,
                          const BevSearchWindow& window, const BevCorrelationParams& params);

}  // namespace osm_graph_slam
