#pragma once
// Stereo features of one rectified pair (ART-SLAM thesis §6.1): FAST corners spread over a grid
// of the left image, ORB descriptors, each matched to the right image's corners along its row
// (rectified: the match lies on the same row, to the left), the disparity optionally refined to
// a sub-pixel by block matching, and triangulated.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "osm_graph_slam/visual/stereo_camera.h"

namespace osm_graph_slam {

struct StereoFeatureParams {
  int fast_threshold = 20;       ///< FAST intensity step; cells without corners retry at 1/2
  int grid_cols = 24;            ///< the left image is split into grid_cols x grid_rows cells ...
  int grid_rows = 8;             ///< ... and each keeps its strongest corners_per_cell corners
  int corners_per_cell = 8;      ///< (1226 x 370 at 24 x 8: 51 x 46 px cells, up to 1,536)
  double row_tolerance = 1.5;    ///< [px] a right match lies this close to the left row
  double min_disparity = 1.0;    ///< [px] farther points (fx b / 1 px = 380 m on KITTI) drop
  double max_disparity = 160.0;  ///< [px] closer than fx b / 160 px (2.4 m on KITTI)
  int max_descriptor_distance = 50;  ///< Hamming bits of the best right match
  double match_ratio = 0.8;          ///< best / second best along the row (distinctness)
  /// [px] sub-pixel refinement of the disparity by block matching ((2r+1)^2 window; 0: the
  /// corners' whole-pixel disparity). Off: on the real KITTI sequence the 11 x 11 refinement
  /// drifted 1.26 % against 1.10 % without (doc/visual.md).
  int block_radius = 0;
  double max_depth = 60.0;  ///< [m] farther points are too uncertain to keep
};

/// Left-image keypoints with descriptors; those with a stereo match carry a 3-D point.
struct StereoFrame {
  std::vector<cv::KeyPoint> keypoints;  ///< left image
  cv::Mat descriptors;                  ///< ORB, one row per keypoint
  std::vector<bool> has_depth;          ///< per keypoint: matched in the right image
  std::vector<float> disparity;         ///< per keypoint [px] (0 without depth)
  std::vector<Eigen::Vector3d> points;  ///< per keypoint, left camera frame (zero without depth)
  size_t stereoMatches() const;
};

StereoFrame extractStereoFrame(const cv::Mat& left, const cv::Mat& right,
                               const StereoCamera& camera, const StereoFeatureParams& params);

}  // namespace osm_graph_slam
