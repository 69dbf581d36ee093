#include "osm_graph_slam/radar/radar_odometry.h"

#include <chrono>
#include <cmath>

#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/common/timing.h"

namespace osm_graph_slam::radar {

bool readParams(const ParamReader& r, RadarOdometryParams& p, std::string* error) {
  RadarFeatureParams& f = p.features;
  r.param("features/detector", f.detector);
  r.param("features/k_strongest", f.k_strongest);
  r.param("features/min_power", f.min_power);
  r.param("features/cfar_train_cells", f.cfar_train_cells);
  r.param("features/cfar_guard_cells", f.cfar_guard_cells);
  r.param("features/cfar_scale", f.cfar_scale);
  r.param("features/cfar_min_power", f.cfar_min_power);
  r.param("features/min_range", f.min_range);
  r.param("features/max_range", f.max_range);
  r.param("features/thinning_cell", f.thinning_cell);
  r.param("features/max_features", f.max_features);
  r.param("features/cart_resolution", f.cart_resolution);
  r.param("features/orb_patch_size", f.orb_patch_size);
  r.param("features/azimuth_clockwise", f.azimuth_clockwise);
  MotionEstimatorParams& m = p.motion;
  r.param("motion/motion_compensation", m.motion_compensation);
  r.param("motion/doppler_correction", m.doppler_correction);
  r.param("motion/doppler_beta", m.doppler_beta);
  r.param("motion/ransac_iterations", m.ransac_iterations);
  r.param("motion/inlier_threshold", m.inlier_threshold);
  r.param("motion/gauss_newton_iterations", m.gauss_newton_iterations);
  r.param("motion/min_inliers", m.min_inliers);
  r.param("motion/seed", m.seed);
  RadarRegistrationParams& g = p.registration;
  r.param("registration/enabled", g.enabled);
  r.param("registration/submap_keyframes", g.submap_keyframes);
  r.param("registration/max_correspondence", g.max_correspondence);
  r.param("registration/normal_neighbours", g.normal_neighbours);
  r.param("registration/max_line_ratio", g.max_line_ratio);
  r.param("registration/iterations", g.iterations);
  r.param("registration/huber", g.huber);
  r.param("registration/min_correspondences", g.min_correspondences);
  r.param("registration/min_translation_ratio", g.min_translation_ratio);
  r.param("registration/search_below_overlap", g.search_below_overlap);
  r.param("registration/yaw_search_deg", g.yaw_search_deg);
  r.param("registration/yaw_search_step_deg", g.yaw_search_step_deg);
  r.param("registration/velocity_from_registration", g.velocity_from_registration);
  r.param("registration/recompensate", g.recompensate);
  r.param("ratio_test", p.ratio_test);
  r.param("keyframe_translation", p.keyframe_translation);
  r.param("keyframe_rotation_deg", p.keyframe_rotation_deg);
  auto fail = [&](const std::string& why) {
    if (error) *error = "radar parameters: " + why;
    return false;
  };
  if (f.detector != "kstrongest" && f.detector != "cfar")
    return fail("features/detector '" + f.detector + "' (kstrongest or cfar)");
  if (f.cart_resolution <= 0.0 || f.max_range <= f.min_range || f.orb_patch_size < 5)
    return fail("features: cart_resolution > 0, max_range > min_range, orb_patch_size >= 5");
  if (m.inlier_threshold <= 0.0 || m.ransac_iterations < 1 || m.min_inliers < 2)
    return fail("motion: inlier_threshold > 0, ransac_iterations >= 1, min_inliers >= 2");
  if (p.ratio_test <= 0.0 || p.ratio_test > 1.0) return fail("ratio_test in (0, 1]");
  if (g.max_correspondence <= 0.0 || g.huber <= 0.0 || g.submap_keyframes < 1)
    return fail("registration: max_correspondence > 0, huber > 0, submap_keyframes >= 1");
  return true;
}

RadarOdometryStep RadarOdometry::process(const RadarPolarScan& scan) {
  RadarOdometryStep step;
  step.time = scan.midTime();
  auto t0 = std::chrono::steady_clock::now();
  step.feature_set = extractFeatures(scan, params_.features);
  step.detections = step.feature_set.detections;
  step.features = int(step.feature_set.features.size());
  step.ms_features = msSince(t0);
  if (!has_previous_) {
    step.first = true;
    step.ok = true;
    has_previous_ = true;
    previous_ = step.feature_set;
    previous_time_ = step.time;
    step.pose = pose_;
    return step;
  }
  t0 = std::chrono::steady_clock::now();
  const std::vector<FeatureMatch> matches =
      matchFeatures(previous_, step.feature_set, params_.ratio_test);
  step.matches = int(matches.size());
  step.ms_matching = msSince(t0);

  t0 = std::chrono::steady_clock::now();
  std::vector<RadarCorrespondence> cs;
  cs.reserve(matches.size());
  const bool cw = params_.features.azimuth_clockwise;
  for (const FeatureMatch& m : matches) {
    const RadarFeature& a = previous_.features[size_t(m.previous)];
    const RadarFeature& b = step.feature_set.features[size_t(m.current)];
    cs.push_back({a.range, b.range, beamDirection(a.azimuth, cw), beamDirection(b.azimuth, cw),
                  a.time, b.time});
  }
  const MotionEstimate est =
      estimateVelocity(std::move(cs), params_.motion, {previous_time_, step.time}, velocity_);
  step.ms_motion = msSince(t0);
  step.ok = est.ok;
  if (est.ok) velocity_ = est.velocity;  // else: constant velocity
  step.velocity = velocity_;
  step.inliers = int(est.inliers.size());
  step.rms_error = est.rms_error;
  const Eigen::Isometry2d previous_pose = pose_;
  step.relative = se2Exp(velocity_, step.time - previous_time_);
  pose_ = pose_ * step.relative;
  step.points = sweepPoints(step.feature_set, step.time);
  if (params_.registration.enabled) refine(step, previous_pose);
  updateKeyframe(step);
  step.pose = pose_;
  previous_ = step.feature_set;
  previous_time_ = step.time;
  return step;
}

std::vector<Eigen::Vector2d> RadarOdometry::sweepPoints(const RadarFeatureSet& set,
                                                        double t_ref) const {
  const MotionEstimatorParams& m = params_.motion;
  return compensatedPoints(set.features, velocity_, t_ref,
                           m.doppler_correction ? m.doppler_beta : 0.0,
                           params_.features.azimuth_clockwise, m.motion_compensation);
}

void RadarOdometry::refine(RadarOdometryStep& step, const Eigen::Isometry2d& previous_pose) {
  const auto t0 = std::chrono::steady_clock::now();
  // The first keyframe is the previous sweep, compensated with the first velocity estimate.
  if (local_map_.empty())
    local_map_.addKeyframe(previous_pose, sweepPoints(previous_, previous_time_));
  const RadarRegistrationParams& rp = params_.registration;
  const double n = double(std::max<size_t>(1, step.points.size()));
  RadarAlignment a = local_map_.align(step.points, pose_);
  if (!step.ok || !a.ok || a.correspondences < rp.search_below_overlap * n) {
    const double step_rad = std::max(0.5, rp.yaw_search_step_deg) * M_PI / 180.0;
    for (double dyaw = step_rad; dyaw <= rp.yaw_search_deg * M_PI / 180.0 + 1e-9; dyaw += step_rad)
      for (double sign : {-1.0, 1.0}) {
        Eigen::Isometry2d guess = pose_;
        guess.linear() = guess.linear() * Eigen::Rotation2Dd(sign * dyaw).toRotationMatrix();
        const RadarAlignment b = local_map_.align(step.points, guess);
        if (b.ok && (!a.ok || b.correspondences > a.correspondences)) a = b;
      }
    ++step.yaw_searches;
  }
  if (a.ok && rp.recompensate) {
    // The sweep was de-skewed with the previous velocity; in a sharp turn from standstill it is
    // off by degrees within the sweep. De-skew again with the registered motion and re-align.
    const Eigen::Vector3d registered =
        se2Log(previous_pose.inverse() * a.pose) / std::max(1e-3, step.time - previous_time_);
    if ((registered - velocity_).cwiseAbs().maxCoeff() > 0.02) {
      const Eigen::Vector3d used = velocity_;
      velocity_ = registered;
      std::vector<Eigen::Vector2d> again = sweepPoints(step.feature_set, step.time);
      const RadarAlignment b = local_map_.align(again, a.pose);
      if (b.ok && b.correspondences >= a.correspondences) {
        a = b;
        step.points = std::move(again);
      } else {
        velocity_ = used;
      }
    }
  }
  step.registration_correspondences = a.correspondences;
  if (a.ok) {
    step.registered = true;
    pose_ = a.pose;
    step.relative = previous_pose.inverse() * pose_;
    // The registered motion predicts the next sweep (and replaces a failed feature velocity).
    if (!step.ok || rp.velocity_from_registration)
      velocity_ = se2Log(step.relative) / std::max(1e-3, step.time - previous_time_);
  }
  step.ms_registration = msSince(t0);
}

void RadarOdometry::updateKeyframe(RadarOdometryStep& step) {
  const Eigen::Isometry2d since = keyframe_pose_.inverse() * pose_;
  const double turned = std::abs(yawOf(since));
  if (has_keyframe_ && since.translation().norm() < params_.keyframe_translation &&
      turned < params_.keyframe_rotation_deg * M_PI / 180.0)
    return;
  has_keyframe_ = true;
  keyframe_pose_ = pose_;
  step.keyframe = true;
  if (params_.registration.enabled) local_map_.addKeyframe(pose_, step.points);
}

}  // namespace osm_graph_slam::radar
