#pragma once
// Stereo visual odometry (D3VIL-SLAM's visual tracker, ART-SLAM thesis §6.1): every pair is
// matched against the current visual keyframe's triangulated points (ORB descriptors, gated
// around the motion model's projection), the pose solved by PnP in RANSAC and refined on the
// inliers (Levenberg-Marquardt on the reprojection error); outliers are the points RANSAC
// rejects. A pair becomes the new keyframe when too few of the keyframe's points are still
// matched. Poses are the left camera's (x right, y down, z forward) in the first pair's frame.
#include <Eigen/Geometry>
#include <optional>

#include "osm_graph_slam/visual/stereo_features.h"

namespace osm_graph_slam {

struct StereoOdometryParams {
  StereoFeatureParams features;
  int max_descriptor_distance = 50;  ///< Hamming bits of a keyframe-to-frame match
  double match_ratio = 0.8;          ///< best / second best within the gate
  /// [px] a keyframe point is matched only within this of where the motion model projects it:
  /// repetitive structure (fences, windows) is aliased beyond its period, and a real KITTI pair
  /// on a construction fence was tracked 12 m off with a 40 px gate (119 inliers). The model's
  /// error at 10 Hz is a few pixels.
  double search_radius = 15.0;
  /// [px] the gate once more when the tight one gives too few inliers (a bump, a sharp turn)
  double wide_search_radius = 60.0;
  /// A pose this far from the motion model's is refused as an aliased consensus (10 Hz: a
  /// vehicle changes its speed by far less than this in 0.1 s). Not before the motion is known.
  double max_correction_trans = 1.0;   ///< [m]
  double max_correction_angle = 0.15;  ///< [rad]
  /// A match whose new corner has its own stereo depth must agree with the predicted depth of
  /// the keyframe point within this fraction (a 1 px disparity error at 20 px is 5 %).
  double depth_tolerance = 0.15;
  double ransac_reprojection = 2.0;  ///< [px] inlier threshold
  int ransac_iterations = 300;
  int min_inliers = 20;  ///< fewer: the pair is not tracked (the motion model carries it)
  /// A new keyframe when fewer than this many of the keyframe's points are inliers: the overlap
  /// is shrinking and a fresh set of points tracks better than a few old ones.
  int keyframe_min_inliers = 150;
  int keyframe_max_frames = 10;  ///< ... or after this many pairs (bounded drift of the model)
};

struct StereoOdometryResult {
  bool tracked = false;  ///< a pose from the images (else the motion model's)
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< left camera in the first's frame
  int stereo_points = 0;                                   ///< of this pair
  int matches = 0;                                         ///< to the keyframe
  int inliers = 0;
  bool new_keyframe = false;
  double features_ms = 0.0, matching_ms = 0.0, pose_ms = 0.0;
};

class StereoOdometry {
 public:
  StereoOdometry(const StereoCamera& camera, const StereoOdometryParams& params);
  /// One rectified pair (8-bit grayscale, same size) taken after the previous one.
  StereoOdometryResult track(const cv::Mat& left, const cv::Mat& right);
  /// Pairs tracked and not tracked so far.
  size_t tracked() const { return tracked_; }
  size_t lost() const { return lost_; }

 private:
  struct Correspondences {
    std::vector<cv::Point3f> object;  ///< keyframe points (keyframe camera frame)
    std::vector<cv::Point2f> image;   ///< their matches in the new left image
  };
  Correspondences match(const StereoFrame& frame, const Eigen::Isometry3d& predicted,
                        double radius) const;
  /// Matches within `radius` and solves; the pose only if it passes the correction gate.
  std::optional<Eigen::Isometry3d> matchAndSolve(const StereoFrame& frame,
                                                 const Eigen::Isometry3d& predicted, double radius,
                                                 StereoOdometryResult& r) const;
  /// keyframe -> camera of the pair (x_camera = T x_keyframe), or nullopt.
  std::optional<Eigen::Isometry3d> solve(const Correspondences& c,
                                         const Eigen::Isometry3d& predicted, int* inliers) const;
  void makeKeyframe(StereoFrame frame, const Eigen::Isometry3d& pose);

  StereoCamera camera_;
  StereoOdometryParams params_;
  std::optional<StereoFrame> keyframe_;
  Eigen::Isometry3d keyframe_pose_ = Eigen::Isometry3d::Identity();  ///< in the first's frame
  Eigen::Isometry3d pose_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();  ///< last pair-to-pair motion
  bool velocity_known_ = false;  ///< from two tracked pairs: until then no correction gate
  int frames_since_keyframe_ = 0;
  size_t tracked_ = 0, lost_ = 0;
};

}  // namespace osm_graph_slam
