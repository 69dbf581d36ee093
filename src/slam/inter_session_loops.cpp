#include "osm_graph_slam/slam/inter_session_loops.h"

#include <algorithm>

namespace osm_graph_slam {
namespace {

double medianOf(std::vector<double>& v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

std::vector<size_t> inconsistentLoops(const std::vector<LoopClosureInput>& loops,
                                      const std::map<uint64_t, Eigen::Isometry3d>& poses,
                                      const std::map<uint64_t, double>& stamps,
                                      const InterSessionLoopParams& params,
                                      const std::function<uint32_t(uint64_t)>& session_of) {
  struct Offset {
    std::pair<uint32_t, uint32_t> sessions;
    double stamp;
    Eigen::Vector2d offset;
  };
  std::vector<std::optional<Offset>> offsets;
  for (const auto& l : loops) {
    const auto from = poses.find(l.from_id), to = poses.find(l.to_id);
    const auto stamp = stamps.find(l.from_id);
    if (from == poses.end() || to == poses.end() || stamp == stamps.end()) {
      offsets.emplace_back();
      continue;
    }
    const Eigen::Vector3d said = (to->second * l.relative_pose).translation();
    offsets.push_back(Offset{{session_of(l.from_id), session_of(l.to_id)},
                             stamp->second,
                             (said - from->second.translation()).head<2>()});
  }
  std::vector<size_t> refused;
  for (size_t i = 0; i < offsets.size(); ++i) {
    if (!offsets[i]) continue;
    std::vector<double> dx, dy;
    for (size_t j = 0; j < offsets.size(); ++j)
      if (j != i && offsets[j] && offsets[j]->sessions == offsets[i]->sessions &&
          std::abs(offsets[j]->stamp - offsets[i]->stamp) <= params.consistency_window) {
        dx.push_back(offsets[j]->offset.x());
        dy.push_back(offsets[j]->offset.y());
      }
    if (static_cast<int>(dx.size()) < params.consistency_min_neighbours) continue;
    const Eigen::Vector2d neighbours(medianOf(dx), medianOf(dy));
    if ((offsets[i]->offset - neighbours).norm() > params.consistency_distance)
      refused.push_back(i);
  }
  return refused;
}

InterSessionLoopSearch::InterSessionLoopSearch(const LoopDetectorParams& loops,
                                               const InterSessionLoopParams& params,
                                               std::shared_ptr<const Logger> logger)
    : params_(params) {
  std::shared_ptr<const Logger> log = logger ? std::move(logger) : std::make_shared<Logger>();
  detector_ = std::make_unique<LoopDetector>(
      loops, [log](LogLevel level, const std::string& msg) { log->log(level, msg); });
}

InterSessionLoopSearch::~InterSessionLoopSearch() = default;

void InterSessionLoopSearch::addToDatabase(uint64_t id, const Eigen::Isometry3d& map_pose,
                                           const PointCloudConstPtr& cloud) {
  if (!cloud) return;
  LoopKeyframe kf;
  kf.id = id;
  kf.odom_pose = map_pose;
  kf.accum_distance = 0.0;
  kf.cloud = cloud;
  if (detector_->addKeyframe(kf)) ++database_size_;
}

std::optional<LoopClosureInput> InterSessionLoopSearch::query(uint64_t id,
                                                              const Eigen::Isometry3d& map_pose,
                                                              const PointCloudConstPtr& cloud) {
  if (!cloud) return std::nullopt;
  ++queries_;
  LoopKeyframe kf;
  kf.id = id;
  kf.odom_pose = map_pose;
  kf.accum_distance = params_.session_gap;
  kf.cloud = cloud;
  const std::optional<DetectedLoop> loop = detector_->detect(kf);
  if (!loop) return std::nullopt;
  LoopClosureInput in;
  in.from_id = loop->from_id;
  in.to_id = loop->to_id;
  in.relative_pose = loop->relative_pose;
  in.information = loop->information;
  return in;
}

}  // namespace osm_graph_slam
