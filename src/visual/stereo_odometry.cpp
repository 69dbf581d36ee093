#include "osm_graph_slam/visual/stereo_odometry.h"

#include <limits>
#include <opencv2/calib3d.hpp>

#include "osm_graph_slam/common/timing.h"

namespace osm_graph_slam {
namespace {

cv::Mat cameraMatrix(const StereoCamera& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
}

void toRvecTvec(const Eigen::Isometry3d& T, cv::Mat& rvec, cv::Mat& tvec) {
  const Eigen::AngleAxisd aa(T.linear());
  const Eigen::Vector3d r = aa.axis() * aa.angle(), t = T.translation();
  rvec = (cv::Mat_<double>(3, 1) << r.x(), r.y(), r.z());
  tvec = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
}

Eigen::Isometry3d fromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  const Eigen::Vector3d r(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (r.norm() > 1e-12) T.linear() = Eigen::AngleAxisd(r.norm(), r.normalized()).matrix();
  T.translation() << tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2);
  return T;
}

}  // namespace

StereoOdometry::StereoOdometry(const StereoCamera& camera, const StereoOdometryParams& params)
    : camera_(camera), params_(params) {}

StereoOdometry::Correspondences StereoOdometry::match(const StereoFrame& frame,
                                                      const Eigen::Isometry3d& predicted,
                                                      double radius) const {
  // predicted: keyframe -> camera. Each keyframe point looks for the new corners near where the
  // prediction projects it; the best must be distinct from the second best.
  Correspondences c;
  const StereoFrame& kf = *keyframe_;
  const double radius2 = radius * radius;
  for (size_t i = 0; i < kf.keypoints.size(); ++i) {
    if (!kf.has_depth[i]) continue;
    const Eigen::Vector3d p = predicted * kf.points[i];
    if (p.z() < 0.5) continue;
    const Eigen::Vector2d uv = camera_.project(p);
    int best = -1, best_distance = std::numeric_limits<int>::max(), second = best_distance;
    for (size_t j = 0; j < frame.keypoints.size(); ++j) {
      const cv::Point2f& q = frame.keypoints[j].pt;
      const double dx = q.x - uv.x(), dy = q.y - uv.y();
      if (dx * dx + dy * dy > radius2) continue;
      const int distance =
          cv::norm(kf.descriptors.row(int(i)), frame.descriptors.row(int(j)), cv::NORM_HAMMING);
      if (distance < best_distance) {
        second = best_distance;
        best_distance = distance;
        best = int(j);
      } else if (distance < second) {
        second = distance;
      }
    }
    if (best < 0 || best_distance > params_.max_descriptor_distance ||
        best_distance > params_.match_ratio * second)
      continue;
    // Confirmed in the right image: where the new corner has a depth of its own, it must be the
    // depth the prediction gives the keyframe point.
    if (frame.has_depth[size_t(best)] &&
        std::abs(frame.points[size_t(best)].z() - p.z()) > params_.depth_tolerance * p.z())
      continue;
    const Eigen::Vector3d& x = kf.points[i];
    c.object.emplace_back(float(x.x()), float(x.y()), float(x.z()));
    c.image.push_back(frame.keypoints[size_t(best)].pt);
  }
  return c;
}

std::optional<Eigen::Isometry3d> StereoOdometry::solve(const Correspondences& c,
                                                       const Eigen::Isometry3d& predicted,
                                                       int* inliers) const {
  *inliers = 0;
  if (static_cast<int>(c.object.size()) < std::max(4, params_.min_inliers)) return std::nullopt;
  cv::Mat rvec, tvec, inlier_index;
  toRvecTvec(predicted, rvec, tvec);
  const cv::Mat K = cameraMatrix(camera_);
  if (!cv::solvePnPRansac(c.object, c.image, K, cv::noArray(), rvec, tvec, true,
                          params_.ransac_iterations, float(params_.ransac_reprojection), 0.999,
                          inlier_index, cv::SOLVEPNP_ITERATIVE))
    return std::nullopt;
  *inliers = inlier_index.rows;
  if (*inliers < params_.min_inliers) return std::nullopt;
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (int k = 0; k < inlier_index.rows; ++k) {
    const int i = inlier_index.at<int>(k);
    object.push_back(c.object[size_t(i)]);
    image.push_back(c.image[size_t(i)]);
  }
  cv::solvePnPRefineLM(object, image, K, cv::noArray(), rvec, tvec);
  return fromRvecTvec(rvec, tvec);
}

std::optional<Eigen::Isometry3d> StereoOdometry::matchAndSolve(const StereoFrame& frame,
                                                               const Eigen::Isometry3d& predicted,
                                                               double radius,
                                                               StereoOdometryResult& r) const {
  auto t0 = std::chrono::steady_clock::now();
  const Correspondences c = match(frame, predicted, radius);
  r.matches = static_cast<int>(c.object.size());
  r.matching_ms += msSince(t0);
  t0 = std::chrono::steady_clock::now();
  std::optional<Eigen::Isometry3d> solved = solve(c, predicted, &r.inliers);
  r.pose_ms += msSince(t0);
  if (!solved) return std::nullopt;
  const Eigen::Isometry3d correction = predicted.inverse() * *solved;
  if (!velocity_known_) return solved;
  if (correction.translation().norm() > params_.max_correction_trans ||
      Eigen::AngleAxisd(correction.linear()).angle() > params_.max_correction_angle) {
    r.inliers = 0;
    return std::nullopt;
  }
  return solved;
}

void StereoOdometry::makeKeyframe(StereoFrame frame, const Eigen::Isometry3d& pose) {
  keyframe_ = std::move(frame);
  keyframe_pose_ = pose;
  frames_since_keyframe_ = 0;
}

StereoOdometryResult StereoOdometry::track(const cv::Mat& left, const cv::Mat& right) {
  StereoOdometryResult r;
  auto t0 = std::chrono::steady_clock::now();
  StereoFrame frame = extractStereoFrame(left, right, camera_, params_.features);
  r.features_ms = msSince(t0);
  r.stereo_points = static_cast<int>(frame.stereoMatches());
  if (!keyframe_) {
    makeKeyframe(std::move(frame), pose_);
    r.tracked = r.new_keyframe = true;
    r.pose = pose_;
    ++tracked_;
    return r;
  }
  // The motion model: the last pair-to-pair motion once more, from the keyframe's view.
  const Eigen::Isometry3d predicted_pose = pose_ * velocity_;
  const Eigen::Isometry3d predicted = predicted_pose.inverse() * keyframe_pose_;
  std::optional<Eigen::Isometry3d> keyframe_to_camera =
      matchAndSolve(frame, predicted, params_.search_radius, r);
  if (!keyframe_to_camera)
    keyframe_to_camera = matchAndSolve(frame, predicted, params_.wide_search_radius, r);
  const Eigen::Isometry3d previous = pose_;
  if (keyframe_to_camera) {
    pose_ = keyframe_pose_ * keyframe_to_camera->inverse();
    r.tracked = true;
    ++tracked_;
  } else {
    pose_ = predicted_pose;  // carried by the motion model; the next pair starts afresh
    ++lost_;
  }
  velocity_ = previous.inverse() * pose_;
  velocity_known_ = velocity_known_ || keyframe_to_camera.has_value();
  r.pose = pose_;
  ++frames_since_keyframe_;
  if (!keyframe_to_camera || r.inliers < params_.keyframe_min_inliers ||
      frames_since_keyframe_ >= params_.keyframe_max_frames) {
    makeKeyframe(std::move(frame), pose_);
    r.new_keyframe = true;
  }
  return r;
}

}  // namespace osm_graph_slam
