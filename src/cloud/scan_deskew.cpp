#include "osm_graph_slam/cloud/scan_deskew.h"

#include <algorithm>
#include <cmath>
#include <vector>

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

PointCloudPtr deskewedScanBySector(const PointCloud& scan, const Eigen::Isometry3d& motion,
                                   double motion_duration, const SweepTiming& timing, int sectors) {
  auto out = std::make_shared<PointCloud>(scan);
  if (!(motion_duration > 1e-9) || timing.period <= 0.0 || sectors < 1) return out;
  const Eigen::AngleAxisd rotation(motion.rotation());
  const Eigen::Vector3d omega = rotation.axis() * rotation.angle() / motion_duration;
  const Eigen::Vector3d velocity = motion.translation() / motion_duration;
  // Sector k covers the sweep's fraction [k, k + 1) / sectors; its motion is taken at its middle.
  const double sector_angle = 2.0 * M_PI / sectors;
  const double direction = timing.clockwise ? -1.0 : 1.0;  // azimuth's change with time
  std::vector<Eigen::Isometry3f> moved_by(sectors);
  for (int k = 0; k < sectors; ++k) {
    const double azimuth = timing.start_azimuth + direction * (k + 0.5) * sector_angle;
    const double dt = sweepTimeOffset(std::cos(azimuth), std::sin(azimuth), timing);
    const Eigen::Vector3d w = omega * dt;
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    if (w.norm() > 1e-12)
      t.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    t.translation() = velocity * dt;
    moved_by[k] = t.cast<float>();
  }
  for (auto& p : out->points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    // In double, as sweepTimeOffset: a float arc tangent puts a return on the cut at its far side.
    double turned = direction * (std::atan2(double(p.y), double(p.x)) - timing.start_azimuth);
    turned -= 2.0 * M_PI * std::floor(turned / (2.0 * M_PI));  // [0, 2 pi)
    const int k = std::min(sectors - 1, static_cast<int>(turned / sector_angle));
    p.getVector3fMap() = moved_by[k] * p.getVector3fMap();
  }
  return out;
}

}  // namespace osm_graph_slam
