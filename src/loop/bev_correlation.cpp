#include "osm_graph_slam/loop/bev_correlation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "osm_graph_slam/common/cell_key.h"

namespace osm_graph_slam {
namespace {

bool isStructure(const PointT& p, const BevCorrelationParams& params) {
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  const double height = p.z + params.sensor_height;
  return height >= params.min_height && height <= params.max_height;
}

int64_t cellKey(int ix, int iy) {
  return packCellKey(ix, iy);
}

}  // namespace

BevLikelihoodField::BevLikelihoodField(const PointCloud& cloud, const BevCorrelationParams& params)
    : cell_(params.cell_size) {
  Eigen::Vector2d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  std::vector<Eigen::Vector2d> points;
  points.reserve(cloud.size());
  for (const auto& p : cloud.points) {
    if (!isStructure(p, params)) continue;
    points.emplace_back(p.x, p.y);
    lo = lo.cwiseMin(points.back());
    hi = hi.cwiseMax(points.back());
  }
  if (points.empty() || !(cell_ > 0.0)) return;
  const int reach = std::max(1, static_cast<int>(std::ceil(3.0 * params.sigma / cell_)));
  origin_ = lo - Eigen::Vector2d::Constant((reach + 1) * cell_);
  width_ = static_cast<int>(std::ceil((hi.x() - origin_.x()) / cell_)) + reach + 2;
  height_ = static_cast<int>(std::ceil((hi.y() - origin_.y()) / cell_)) + reach + 2;
  std::vector<uint8_t> occupied(static_cast<size_t>(width_) * height_, 0);
  for (const auto& p : points) {
    const int ix = static_cast<int>((p.x() - origin_.x()) / cell_);
    const int iy = static_cast<int>((p.y() - origin_.y()) / cell_);
    occupied[static_cast<size_t>(iy) * width_ + ix] = 1;
  }
  // Kernel over cell-centre distances, stamped with max around every occupied cell.
  const int side = 2 * reach + 1;
  std::vector<float> kernel(static_cast<size_t>(side) * side, 0.f);
  const double inv_two_sigma_sq = 1.0 / (2.0 * params.sigma * params.sigma);
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      const double d_sq = (dx * dx + dy * dy) * cell_ * cell_;
      if (d_sq <= 9.0 * params.sigma * params.sigma) {
        kernel[(dy + reach) * side + dx + reach] =
            static_cast<float>(std::exp(-d_sq * inv_two_sigma_sq));
      }
    }
  }
  values_.assign(occupied.size(), 0.f);
  for (int iy = 0; iy < height_; ++iy) {
    for (int ix = 0; ix < width_; ++ix) {
      if (!occupied[static_cast<size_t>(iy) * width_ + ix]) continue;
      ++occupied_;
      for (int dy = -reach; dy <= reach; ++dy) {
        float* row = &values_[static_cast<size_t>(iy + dy) * width_ + ix];
        const float* k = &kernel[(dy + reach) * side + reach];
        for (int dx = -reach; dx <= reach; ++dx) row[dx] = std::max(row[dx], k[dx]);
      }
    }
  }
}

std::vector<Eigen::Vector2f> bevQueryPoints(const PointCloud& cloud,
                                            const BevCorrelationParams& params) {
  const double spacing = std::max(1e-3, params.query_point_spacing);
  const double max_range_sq = params.max_range * params.max_range;
  struct Sum {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    int count = 0;
  };
  std::unordered_map<int64_t, Sum> cells;
  for (const auto& p : cloud.points) {
    if (!isStructure(p, params)) continue;
    if (static_cast<double>(p.x) * p.x + static_cast<double>(p.y) * p.y > max_range_sq) continue;
    Sum& s = cells[cellKey(static_cast<int>(std::floor(p.x / spacing)),
                           static_cast<int>(std::floor(p.y / spacing)))];
    s.sum += Eigen::Vector2d(p.x, p.y);
    ++s.count;
  }
  std::vector<std::pair<int64_t, Eigen::Vector2f>> sorted;  // deterministic order
  sorted.reserve(cells.size());
  for (const auto& [key, s] : cells) sorted.push_back({key, (s.sum / s.count).cast<float>()});
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Eigen::Vector2f> out;
  out.reserve(sorted.size());
  for (const auto& item : sorted) out.push_back(item.second);
  return out;
}

BevSearchResult searchBev(const BevLikelihoodField& field,
                          const std::vector<Eigen::Vector2f>& query_points,
                          const BevSearchWindow& window, const BevCorrelationParams& params) {
  BevSearchResult result;
  result.query_points = static_cast<int>(query_points.size());
  if (field.empty() || query_points.empty()) return result;
  const double cell = field.cellSize();
  const int reach = std::max(0, static_cast<int>(std::floor(window.translation_radius / cell)));
  const int side = 2 * reach + 1;
  const int yaw_reach =
      params.yaw_step > 0.0
          ? std::max(0, static_cast<int>(std::floor(window.yaw_radius / params.yaw_step)))
          : 0;
  const int yaws = 2 * yaw_reach + 1;
  const int w = field.width(), h = field.height();
  const float* values = field.values().data();
  // Scores over the full square per yaw; offsets outside the disc are masked afterwards.
  std::vector<float> scores(static_cast<size_t>(yaws) * side * side, 0.f);
  std::vector<int> offset_index(static_cast<size_t>(side) * side);
  for (int j = -reach; j <= reach; ++j) {
    for (int i = -reach; i <= reach; ++i) offset_index[(j + reach) * side + i + reach] = j * w + i;
  }
  const float inv_cell = static_cast<float>(1.0 / cell);
  for (int k = 0; k < yaws; ++k) {
    const double yaw = window.center.z() + (k - yaw_reach) * params.yaw_step;
    const float c = static_cast<float>(std::cos(yaw)), s = static_cast<float>(std::sin(yaw));
    float* slice = &scores[static_cast<size_t>(k) * side * side];
    for (const auto& q : query_points) {
      // Nearest cell of the point at the window's centre translation.
      const float x =
          c * q.x() - s * q.y() + static_cast<float>(window.center.x() - field.origin().x());
      const float y =
          s * q.x() + c * q.y() + static_cast<float>(window.center.y() - field.origin().y());
      const int bx = static_cast<int>(std::floor(x * inv_cell));
      const int by = static_cast<int>(std::floor(y * inv_cell));
      if (bx - reach >= 0 && by - reach >= 0 && bx + reach < w && by + reach < h) {
        const float* base = values + static_cast<ptrdiff_t>(by) * w + bx;
        for (size_t o = 0; o < offset_index.size(); ++o) slice[o] += base[offset_index[o]];
      } else {
        for (int j = -reach; j <= reach; ++j) {
          for (int i = -reach; i <= reach; ++i) {
            slice[(j + reach) * side + i + reach] += field.at(bx + i, by + j);
          }
        }
      }
    }
  }
  const float inv_n = 1.f / static_cast<float>(query_points.size());
  const double radius_cells_sq =
      (window.translation_radius / cell) * (window.translation_radius / cell);
  auto inside = [&](int i, int j) {
    return i >= -reach && i <= reach && j >= -reach && j <= reach &&
           static_cast<double>(i * i + j * j) <= radius_cells_sq;
  };
  auto score = [&](int k, int i, int j) {
    return scores[(static_cast<size_t>(k) * side + (j + reach)) * side + i + reach] * inv_n;
  };
  auto pose = [&](int k, int i, int j) {
    return Eigen::Vector3d(window.center.x() + i * cell, window.center.y() + j * cell,
                           window.center.z() + (k - yaw_reach) * params.yaw_step);
  };
  int best_k = -1, best_i = 0, best_j = 0;
  for (int k = 0; k < yaws; ++k) {
    for (int j = -reach; j <= reach; ++j) {
      for (int i = -reach; i <= reach; ++i) {
        if (!inside(i, j)) continue;
        ++result.poses;
        if (best_k < 0 || score(k, i, j) > result.best_score) {
          best_k = k, best_i = i, best_j = j;
          result.best_score = score(k, i, j);
        }
      }
    }
  }
  if (best_k < 0) return result;
  result.valid = true;
  result.best = pose(best_k, best_i, best_j);
  // Runner-up: the best local maximum (over its translation and yaw neighbours inside the window)
  // far enough from the best pose to be another placement, not the same basin.
  const double separation_sq = (params.peak_separation / cell) * (params.peak_separation / cell);
  for (int k = 0; k < yaws; ++k) {
    for (int j = -reach; j <= reach; ++j) {
      for (int i = -reach; i <= reach; ++i) {
        if (!inside(i, j)) continue;
        const double di = i - best_i, dj = j - best_j;
        if (di * di + dj * dj < separation_sq) continue;
        const float s = score(k, i, j);
        if (s <= result.runner_up_score) continue;
        bool peak = true;
        for (int dk = -1; dk <= 1 && peak; ++dk) {
          if (k + dk < 0 || k + dk >= yaws) continue;
          for (int dj2 = -1; dj2 <= 1 && peak; ++dj2) {
            for (int di2 = -1; di2 <= 1 && peak; ++di2) {
              if ((dk || dj2 || di2) && inside(i + di2, j + dj2) &&
                  score(k + dk, i + di2, j + dj2) > s) {
                peak = false;
              }
            }
          }
        }
        if (!peak) continue;
        result.runner_up_score = s;
        result.runner_up = pose(k, i, j);
        result.valid_runner_up = true;
      }
    }
  }
  return result;
}

}  // namespace osm_graph_slam
