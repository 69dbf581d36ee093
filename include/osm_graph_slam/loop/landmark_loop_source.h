#pragma once
// Loop candidates from landmark geometry (GeoSLAM geometric hierarchies, doc/landmarks.md): the
// trunks and poles of every stored keyframe's cloud go into a LandmarkPlaceRecognizer; a query
// proposes one earlier keyframe and the 2D transform between the two. LoopDetector verifies the
// proposal exactly like a Scan Context candidate. Stored keyframes are numbered like the
// detector's database (one add() per stored entry).
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/landmarks/landmark_extraction.h"
#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"

namespace osm_graph_slam {

/// Landmark extraction for the prefiltered keyframe cloud (0.5 m voxels) that loop detection and
/// localisation get, sparser than the raw scans LandmarkExtractionParams' defaults are set for.
LandmarkExtractionParams loopLandmarkExtractionDefaults();

struct LandmarkProposal {
  size_t index = 0;  ///< database index of the proposed keyframe
  /// Query keyframe in the proposed keyframe's frame (planar: x, y, yaw; z = 0).
  Eigen::Isometry3d relative_pose = Eigen::Isometry3d::Identity();
  int inliers = 0;
  double inlier_ratio = 0.0;
};

struct LandmarkSourceStats {
  int landmarks = 0;           ///< extracted from the last cloud
  double extraction_ms = 0.0;  ///< 0 when the last cloud's landmarks were cached
  double query_ms = 0.0;       ///< hierarchy + retrieval + hierarchical matching
};

class LandmarkLoopSource {
 public:
  LandmarkLoopSource(const LandmarkExtractionParams& extraction,
                     const LandmarkPlaceRecognitionParams& recognition);
  ~LandmarkLoopSource();

  /// Best earlier keyframe (index < index_limit) by landmark geometry, or nothing.
  std::optional<LandmarkProposal> propose(const PointCloudConstPtr& cloud, size_t index_limit);
  /// Stores a keyframe's landmarks (extracted once when propose() saw the same cloud).
  void add(const PointCloudConstPtr& cloud);

  size_t size() const;
  const LandmarkSourceStats& lastStats() const { return stats_; }

 private:
  const std::vector<Eigen::Vector2d>& landmarksOf(const PointCloudConstPtr& cloud);

  LandmarkExtractionParams extraction_;
  std::unique_ptr<LandmarkPlaceRecognizer> recognizer_;
  // The last cloud's landmarks: process() queries and then stores the same keyframe. Holding
  // the pointer keeps its address from being reused by another cloud.
  PointCloudConstPtr cached_cloud_;
  std::vector<Eigen::Vector2d> cached_landmarks_;
  LandmarkSourceStats stats_;
};

}  // namespace osm_graph_slam
