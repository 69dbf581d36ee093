#pragma once
// Wall line segments from flattened wall points (OSM thesis §3.2, Algorithm 3.1): repeated RANSAC
// line fits; Euclidean clustering of the inliers keeping the largest cluster; endpoints from the
// extreme signed projections on the line direction (Appendix A.1); least-squares refinement on the
// cluster; remove the cluster and repeat.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

struct LineSegmentExtractorParams {
  /// Coincident points (a wall column flattened to z = 0) are merged on this 2D grid and weighted
  /// by their count; cluster sizes count merged points. 0 disables merging.
  double merge_resolution = 0.15;
  double distance_threshold = 0.1;  ///< RANSAC inlier distance to the line [m]
  int max_iterations = 80;          ///< RANSAC hypotheses per extracted line
  /// The second sample is drawn from the first one's cell of this size: walls are local, so a
  /// pair of points on the same wall is found in far fewer draws than with uniform sampling.
  double sample_cell = 3.0;
  double cluster_tolerance = 0.6;   ///< largest gap along the line inside one cluster [m]
  /// Merged points a segment needs. 5 (was 10) keeps short and distant walls: on the simulated
  /// drives the building error fell from 0.504 to 0.322 m (60 s; doc/backend.md).
  int min_cluster_size = 5;
  double min_segment_length = 1.0;  ///< [m]
  int max_segments = 64;
  int max_consecutive_rejects = 8;  ///< stop after this many rejected clusters in a row
  bool refine = true;               ///< least-squares refit on the cluster
  uint32_t seed = 42;               ///< RNG seed: the same input and seed give the same segments
};

struct LineSegmentStats {
  size_t input_points = 0;
  size_t merged_points = 0;
  int lines_tried = 0;  ///< RANSAC rounds (Algorithm 3.1 loop iterations)
  int hypotheses = 0;   ///< RANSAC hypotheses scored
  double ms = 0.0;
};

class LineSegmentExtractor {
 public:
  explicit LineSegmentExtractor(const LineSegmentExtractorParams& params = {}) : params_(params) {}

  /// Segments of the 2D points (non-finite points are ignored). Deterministic for a given seed.
  std::vector<LineSegment2> extract(const std::vector<Eigen::Vector2d>& points,
                                    LineSegmentStats* stats = nullptr) const;
  /// Same on the x, y of a (flattened) cloud.
  std::vector<LineSegment2> extract(const PointCloud& cloud,
                                    LineSegmentStats* stats = nullptr) const;

  const LineSegmentExtractorParams& params() const { return params_; }

 private:
  LineSegmentExtractorParams params_;
};

}  // namespace osm_graph_slam
