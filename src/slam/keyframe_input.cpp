#include "osm_graph_slam/slam/keyframe_input.h"

#include "osm_graph_slam/common/attitude.h"

namespace osm_graph_slam {

KeyframeInput keyframeInput(const Keyframe& kf, const TrackResult& track) {
  KeyframeInput input;
  input.id = kf.id;
  input.stamp = kf.stamp;
  input.odom_pose = kf.pose;
  input.accum_distance = kf.accum_distance;
  if (track.registration.converged) {
    // The multi-cue tracker's match is not the edge's evidence (TrackResult): the edge keeps
    // the fitness model's middle, loosened by the prediction error as any other.
    if (track.registration_is_edge) {
      input.odom_fitness = track.registration.fitness;
      input.odom_hessian = track.registration.hessian;
    }
    input.odom_prediction_error = track.prediction_error;
  }
  input.reanchored = track.reanchored;
  input.cloud = kf.cloud;
  return input;
}

KeyframeAiding::KeyframeAiding(const SensorInputsParams& params,
                               std::optional<double> known_initial_yaw, bool heading_from_imu,
                               bool keep_fixes)
    : sensors_(params),
      known_initial_yaw_(known_initial_yaw),
      heading_from_imu_(heading_from_imu),
      keep_fixes_(keep_fixes) {}

ScanAiding KeyframeAiding::at(double stamp) const {
  ScanAiding out;
  if (const auto imu = sensors_.attitudeAt(stamp)) {
    out.gravity_roll_pitch = Eigen::Vector2d(imu->roll, imu->pitch);
    out.imu_orientation = imu->orientation;
  }
  if (const auto gnss = sensors_.gnssPositionAt(stamp)) {
    out.gnss_position = gnss->xy;
    if (gnss->std_xy > 0.0) out.gnss_std = gnss->std_xy;
    out.gnss_altitude = gnss->altitude;
  }
  return out;
}

std::optional<FirstHeading> KeyframeAiding::aid(const ScanAiding& sensors, KeyframeInput& kf) {
  kf.gravity_roll_pitch = sensors.gravity_roll_pitch;
  // The INS yaw is a heading prior only with ins_heading_std > 0; dumps keep it for replays.
  if (sensors.imu_orientation) kf.ins_yaw = yawOf(*sensors.imu_orientation);
  // Every fix is attached (dumps keep them, so a replay can turn GNSS priors on); the back-end
  // uses those after the first only with GNSS priors.
  kf.gnss_position = sensors.gnss_position;
  if (sensors.gnss_position) {
    kf.gnss_std = sensors.gnss_std;
    kf.gnss_altitude = sensors.gnss_altitude;
  }
  if (first_seen_) return std::nullopt;
  first_seen_ = true;
  if (!keep_fixes_) sensors_.stopKeepingFixes();  // only the first keyframe's anchors the map
  return decideFirstHeading(sensors, kf.stamp);
}

FirstHeading KeyframeAiding::decideFirstHeading(const ScanAiding& sensors, double stamp) const {
  FirstHeading out;
  if (known_initial_yaw_) {
    out.yaw = known_initial_yaw_;
    return out;
  }
  if (!heading_from_imu_) return out;
  out.from_imu = true;
  if (sensors.imu_orientation) {
    out.yaw = yawOf(*sensors.imu_orientation);
    return out;
  }
  // The IMU's sample at the stamp may be missing (its first scans lost at start-up, one sample
  // at the drive's start): a recent one is still far better than the odometry frame's heading.
  const InitialHeading heading = sensors_.initialHeading(stamp);
  out.yaw = heading.yaw;
  out.warning = heading.warning;
  out.from_imu = heading.yaw.has_value();
  return out;
}

}  // namespace osm_graph_slam
