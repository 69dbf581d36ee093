#include "osm_graph_slam/landmarks/landmark_map.h"

#include <cmath>
#include <unordered_map>

#include "osm_graph_slam/common/cell_key.h"

namespace osm_graph_slam {
namespace {

struct Group {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  double sum_sq = 0.0;  ///< of |p|^2, for the spread
  int count = 0;
  int last_keyframe = -1;
  Eigen::Vector2d mean() const { return sum / count; }
};

}  // namespace

std::vector<MapLandmark> discoverLandmarks(const std::vector<KeyframeLandmarks>& keyframes,
                                           const LandmarkMapParams& params) {
  const double delta = std::max(1e-3, params.association_distance);
  std::vector<Group> groups;
  // Groups by the cell of their first observation; a mean stays within delta of it, so the
  // 5 x 5 cells around an observation hold every group that can take it.
  std::unordered_map<int64_t, std::vector<int>> cells;
  for (size_t k = 0; k < keyframes.size(); ++k) {
    for (const Eigen::Vector2d& local : keyframes[k].landmarks) {
      const Eigen::Vector2d p = keyframes[k].pose.transform(local);
      const int64_t cx = static_cast<int64_t>(std::floor(p.x() / delta));
      const int64_t cy = static_cast<int64_t>(std::floor(p.y() / delta));
      int best = -1;
      double best_d = delta;
      for (int64_t dx = -2; dx <= 2; ++dx) {
        for (int64_t dy = -2; dy <= 2; ++dy) {
          const auto it = cells.find(packCellKey(cx + dx, cy + dy));
          if (it == cells.end()) continue;
          for (int g : it->second) {
            if (groups[g].last_keyframe == static_cast<int>(k)) continue;
            const double d = (groups[g].mean() - p).norm();
            if (d < best_d) best_d = d, best = g;
          }
        }
      }
      if (best < 0) {
        best = static_cast<int>(groups.size());
        groups.emplace_back();
        cells[packCellKey(cx, cy)].push_back(best);
      }
      Group& g = groups[best];
      g.sum += p;
      g.sum_sq += p.squaredNorm();
      ++g.count;
      g.last_keyframe = static_cast<int>(k);
    }
  }
  std::vector<MapLandmark> out;
  for (const Group& g : groups) {
    if (g.count < std::max(1, params.min_observations)) continue;
    MapLandmark m;
    m.position = g.mean();
    m.observations = g.count;
    m.spread = std::sqrt(std::max(0.0, g.sum_sq / g.count - m.position.squaredNorm()));
    out.push_back(m);
  }
  return out;
}

LandmarkMapRecognizer::LandmarkMapRecognizer(std::vector<MapLandmark> landmarks,
                                             const std::vector<Eigen::Vector2d>& path,
                                             const LandmarkMapParams& params,
                                             const LandmarkPlaceRecognitionParams& recognition)
    : landmarks_(std::move(landmarks)),
      recognizer_(std::make_unique<LandmarkPlaceRecognizer>(recognition)) {
  // A path that comes back reuses the tiles of its first pass.
  centres_ = spacedPathPoints(path, std::max(1.0, params.tile_spacing));
  const double r2 = params.tile_radius * params.tile_radius;
  for (const Eigen::Vector2d& c : centres_) {
    std::vector<Eigen::Vector2d> tile;
    for (const MapLandmark& m : landmarks_)
      if ((m.position - c).squaredNorm() <= r2) tile.push_back(m.position - c);
    recognizer_->add(tile);  // a tile with too few landmarks keeps its number, never matches
  }
}

LandmarkMapRecognizer::~LandmarkMapRecognizer() = default;

std::optional<LandmarkMapMatch> LandmarkMapRecognizer::query(
    const std::vector<Eigen::Vector2d>& landmarks) const {
  const LandmarkQueryResult result = recognizer_->query(landmarks, recognizer_->size());
  if (!result.found || result.keyframe < 0) return std::nullopt;
  LandmarkMapMatch out;
  out.tile = result.keyframe;
  out.match = result.match;
  const Eigen::Vector2d& c = centres_[static_cast<size_t>(result.keyframe)];
  out.pose = Pose2(c.x(), c.y(), 0.0) * planarPose(result.match.transform);
  return out;
}

}  // namespace osm_graph_slam
