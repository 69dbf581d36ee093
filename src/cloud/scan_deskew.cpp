#include "osm_graph_slam/cloud/scan_deskew.h"

#include <cmath>

namespace osm_graph_slam {

double sweepTimeOffset(double x, double y, const SweepTiming& timing) {
  const double turned = timing.clockwise ? timing.start_azimuth - std::atan2(y, x)
                                         : std::atan2(y, x) - timing.start_azimuth;
  double f = turned / (2.0 * M_PI);
  f -= std::floor(f);  // fraction of the sweep done, [0, 1)
  return (f - timing.stamp_fraction) * timing.period;
}

void deskewCloud(PointCloud& cloud, const Eigen::Isometry3d& sensor_to_base,
                 const Eigen::Isometry3d& motion, double motion_duration,
                 const SweepTiming& timing) {
  if (!(motion_duration > 1e-9) || timing.period <= 0.0) return;
  // Constant velocity: the motion over dt is the period's motion scaled in its twist (first
  // order in the rotation angle, which is at most a few degrees per sweep).
  const Eigen::AngleAxisd rotation(motion.rotation());
  const Eigen::Vector3d omega = rotation.axis() * rotation.angle() / motion_duration;
  const Eigen::Vector3d velocity = motion.translation() / motion_duration;
  const Eigen::Isometry3d base_to_sensor = sensor_to_base.inverse();
  for (auto& p : cloud.points) {
    const Eigen::Vector3d b(p.x, p.y, p.z);
    if (!b.allFinite()) continue;
    const Eigen::Vector3d s = base_to_sensor * b;
    const double dt = sweepTimeOffset(s.x(), s.y(), timing);
    const Eigen::Vector3d w = omega * dt;
    const double angle = w.norm();
    const Eigen::Vector3d moved =
        (angle > 1e-12 ? Eigen::AngleAxisd(angle, w / angle) * b : b) + velocity * dt;
    p.x = static_cast<float>(moved.x());
    p.y = static_cast<float>(moved.y());
    p.z = static_cast<float>(moved.z());
  }
}

PointCloudPtr deskewedCopy(const PointCloud& cloud, const Eigen::Isometry3d& sensor_to_base,
                           const Eigen::Isometry3d& motion, double motion_duration,
                           const SweepTiming& timing) {
  auto out = std::make_shared<PointCloud>(cloud);
  deskewCloud(*out, sensor_to_base, motion, motion_duration, timing);
  return out;
}

}  // namespace osm_graph_slam
