#include "osm_graph_slam/loop/landmark_loop_source.h"

#include <chrono>

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

Eigen::Isometry3d toIsometry3d(const Eigen::Isometry2d& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear().topLeftCorner<2, 2>() = t.linear();
  out.translation().head<2>() = t.translation();
  return out;
}

}  // namespace

LandmarkLoopSource::LandmarkLoopSource(const LandmarkExtractionParams& extraction,
                                       const LandmarkPlaceRecognitionParams& recognition)
    : extraction_(extraction),
      recognizer_(std::make_unique<LandmarkPlaceRecognizer>(recognition)) {}

LandmarkLoopSource::~LandmarkLoopSource() = default;

size_t LandmarkLoopSource::size() const {
  return recognizer_->size();
}

const std::vector<Eigen::Vector2d>& LandmarkLoopSource::landmarksOf(
    const PointCloudConstPtr& cloud) {
  stats_.extraction_ms = 0.0;
  if (cloud != cached_cloud_) {
    const auto start = Clock::now();
    cached_landmarks_ = cloud ? landmarkCenters(extractLandmarks(*cloud, extraction_))
                              : std::vector<Eigen::Vector2d>();
    cached_cloud_ = cloud;
    stats_.extraction_ms = msSince(start);
  }
  stats_.landmarks = static_cast<int>(cached_landmarks_.size());
  return cached_landmarks_;
}

std::optional<LandmarkProposal> LandmarkLoopSource::propose(const PointCloudConstPtr& cloud,
                                                            size_t index_limit) {
  stats_ = LandmarkSourceStats();
  const auto& landmarks = landmarksOf(cloud);
  const auto start = Clock::now();
  const LandmarkQueryResult result = recognizer_->query(landmarks, index_limit);
  stats_.query_ms = msSince(start);
  if (!result.found) return std::nullopt;
  LandmarkProposal proposal;
  proposal.index = static_cast<size_t>(result.keyframe);
  proposal.relative_pose = toIsometry3d(result.match.transform);
  proposal.inliers = result.match.inliers;
  proposal.inlier_ratio = result.match.inlier_ratio;
  return proposal;
}

void LandmarkLoopSource::add(const PointCloudConstPtr& cloud) {
  recognizer_->add(landmarksOf(cloud));
  // A stored cloud is not queried again: release it.
  cached_cloud_.reset();
}

}  // namespace osm_graph_slam

namespace osm_graph_slam {

LandmarkExtractionParams loopLandmarkExtractionDefaults() {
  LandmarkExtractionParams p;
  // The prefiltered keyframe cloud has one point per 0.5 m voxel: a trunk's band holds ~4
  // points stacked 0.5 m apart (doc/landmarks.md section 7).
  p.slice_height = 0.5;
  p.min_points = 3;
  p.min_confidence = 0.15;
  return p;
}

}  // namespace osm_graph_slam
