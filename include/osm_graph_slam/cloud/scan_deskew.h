#pragma once
// Motion compensation of a spinning LiDAR's sweep (deskewing): each point was measured at its
// own time within the sweep, from a sensor that kept moving; the scan's points are moved to where
// they would have been seen at the scan's stamp, assuming constant velocity over the sweep.
#include <Eigen/Geometry>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

/// When each azimuth of a sweep is measured. Defaults: a Velodyne/Ouster-style head turning
/// clockwise seen from above (azimuth decreasing), the sweep cut behind the sensor and the stamp
/// at the sweep's middle, when the head faces forward (KITTI raw; the simulator's convention).
struct SweepTiming {
  double period = 0.1;    ///< [s] one revolution (10 Hz)
  bool clockwise = true;  ///< azimuth atan2(y, x) decreases with time
  /// [s] the stamp's time after the sweep's start, as a fraction of the period (0.5: mid-sweep).
  double stamp_fraction = 0.5;
  /// [rad] sensor-frame azimuth where the sweep starts (pi: behind the sensor)
  double start_azimuth = 3.14159265358979323846;
};

/// [s] time of a point at sensor-frame (x, y) relative to the stamp, in
/// [-stamp_fraction, 1 - stamp_fraction) * period.
double sweepTimeOffset(double x, double y, const SweepTiming& timing);

/// Moves every point of `cloud` (in base_link) to the base_link frame at the stamp. The point's
/// time comes from its azimuth in the sensor frame (sensor_to_base maps sensor to base_link);
/// `motion` is base_link's pose change over `motion_duration` seconds at constant velocity (the
/// tracker's last motion, a filter's prediction), so a point taken dt after the stamp is moved by
/// motion^(dt / motion_duration).
void deskewCloud(PointCloud& cloud, const Eigen::Isometry3d& sensor_to_base,
                 const Eigen::Isometry3d& motion, double motion_duration,
                 const SweepTiming& timing);

/// A deskewed copy of `cloud` (deskewCloud on a copy): the input may be shared (a message's
/// cloud, a cloud a registration back-end keeps prepared) and must stay as it came.
PointCloudPtr deskewedCopy(const PointCloud& cloud, const Eigen::Isometry3d& sensor_to_base,
                           const Eigen::Isometry3d& motion, double motion_duration,
                           const SweepTiming& timing);

/// deskewedCopy of a full-resolution scan in the sensor's own frame (sensor_to_base identity),
/// with the motion computed once per azimuth sector of the sweep instead of per point: the
/// multi-cue tracker deskews ~120 000 points a scan, and a rotation built per point took 9 of
/// its 25 ms. A sector lasts period / sectors (49 us at 2048 and 10 Hz); the sectors start at
/// the sweep's cut, so none straddles it.
PointCloudPtr deskewedScanBySector(const PointCloud& scan, const Eigen::Isometry3d& motion,
                                   double motion_duration, const SweepTiming& timing,
                                   int sectors = 2048);

}  // namespace osm_graph_slam
