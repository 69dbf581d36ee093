#pragma once
// Scan-to-scan radar odometry: features of each sweep (radar_features.h) matched against the
// previous sweep's, the body velocity from motion-compensated RANSAC with Doppler correction
// (radar_motion.h), and the relative pose between the sweeps' reference (mid) times. Frames:
// x forward, y left, yaw counter-clockwise (seen from above).
#include <Eigen/Geometry>
#include <string>

#include "osm_graph_slam/radar/radar_features.h"
#include "osm_graph_slam/radar/radar_motion.h"
#include "osm_graph_slam/radar/radar_registration.h"

namespace osm_graph_slam {
class ParamReader;
namespace radar {

struct RadarOdometryParams {
  RadarFeatureParams features;
  MotionEstimatorParams motion;
  RadarRegistrationParams registration;
  double ratio_test = 0.8;            ///< nearest / second-nearest Hamming distance
  double keyframe_translation = 5.0;  ///< [m] a new keyframe after this much travel
  double keyframe_rotation_deg = 10.0;
};

/// Reads "features/...", "motion/...", "ratio_test", "keyframe_*" (config/radar.yaml).
/// False with the reason in error for an unknown detector or a non-positive size.
bool readParams(const ParamReader& reader, RadarOdometryParams& params, std::string* error);

struct RadarOdometryStep {
  bool ok = false;     ///< a velocity was estimated (else constant velocity was assumed)
  bool first = false;  ///< the first sweep: nothing to match
  double time = 0.0;   ///< [s] the sweep's reference time (mid time)
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Isometry2d relative = Eigen::Isometry2d::Identity();  ///< this sweep in the previous one
  Eigen::Isometry2d pose = Eigen::Isometry2d::Identity();      ///< in the first sweep's frame
  int detections = 0, features = 0, matches = 0, inliers = 0;
  double rms_error = 0.0;
  bool registered = false;  ///< the pose was refined against the local map
  bool keyframe = false;    ///< this sweep became a keyframe of the local map
  int registration_correspondences = 0;
  int yaw_searches = 0;  ///< 1 when the yaw hypotheses were tried
  double ms_features = 0.0, ms_matching = 0.0, ms_motion = 0.0, ms_registration = 0.0;
  RadarFeatureSet feature_set;  ///< this sweep's features (for loop detection / maps)
  /// feature_set's points at the sweep's reference time (motion- and Doppler-compensated), in
  /// the sweep's frame; empty for the first sweep.
  std::vector<Eigen::Vector2d> points;
};

class RadarOdometry {
 public:
  explicit RadarOdometry(const RadarOdometryParams& params)
      : params_(params), local_map_(params.registration) {}
  RadarOdometryStep process(const RadarPolarScan& scan);
  const RadarOdometryParams& params() const { return params_; }
  /// Forgets the previous sweep and the velocity (a gap in the input): the next sweep is matched
  /// against nothing (first = true) and the pose continues from where it is.
  void restart() {
    has_previous_ = false;
    velocity_.setZero();
    // The local map stays in the odometry frame, but the vehicle may have moved unseen.
    local_map_.clear();
    has_keyframe_ = false;
  }

 private:
  RadarOdometryParams params_;
  bool has_previous_ = false;
  RadarFeatureSet previous_;
  double previous_time_ = 0.0;
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();
  Eigen::Isometry2d pose_ = Eigen::Isometry2d::Identity();
  RadarLocalMap local_map_;

  /// The sweep's points at its reference time with the current velocity.
  std::vector<Eigen::Vector2d> sweepPoints(const RadarFeatureSet& set, double t_ref) const;
  void refine(RadarOdometryStep& step, const Eigen::Isometry2d& previous_pose);
  void updateKeyframe(RadarOdometryStep& step);
  bool has_keyframe_ = false;
  Eigen::Isometry2d keyframe_pose_ = Eigen::Isometry2d::Identity();
};

}  // namespace radar
}  // namespace osm_graph_slam
