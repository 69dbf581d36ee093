#include "osm_graph_slam/eval/radar_evaluation.h"

#include <cmath>
#include <map>

#include "osm_graph_slam/io/oxford_radar.h"

namespace osm_graph_slam::radar {

OxfordEvaluation evaluateOxfordDrive(const std::string& drive_dir, const std::string& odometry_csv,
                                     const RadarOdometryParams& params) {
  OxfordEvaluation ev;
  const auto stamps = readOxfordRadarTimestamps(drive_dir + "/radar.timestamps");
  if (!stamps) {
    ev.error = stamps.error;
    return ev;
  }
  const auto gt = readOxfordRadarOdometry(odometry_csv);
  if (!gt) {
    ev.error = gt.error;
    return ev;
  }
  std::map<std::pair<int64_t, int64_t>, OxfordRadarOdometry> by_pair;
  for (const OxfordRadarOdometry& o : gt.value)
    if (o.has_radar_stamps) by_pair[{o.destination_radar_stamp_us, o.source_radar_stamp_us}] = o;
  if (stamps.value.empty()) {
    ev.error = drive_dir + "/radar.timestamps: no scans";
    return ev;
  }
  const int64_t origin = stamps.value.front().stamp_us;
  RadarOdometry odometry(params);
  Eigen::Isometry2d chained_est = Eigen::Isometry2d::Identity();
  Eigen::Isometry2d chained_gt = Eigen::Isometry2d::Identity();
  int64_t previous_stamp = -1;
  for (const OxfordRadarStamp& s : stamps.value) {
    const auto scan = readOxfordRadarPng(oxfordRadarPngPath(drive_dir, s.stamp_us));
    if (!scan) {  // a bad scan breaks the chain: the next pair starts afresh
      ev.error += scan.error + "\n";
      odometry = RadarOdometry(params);
      previous_stamp = -1;
      continue;
    }
    const RadarOdometryStep step = odometry.process(fromOxford(scan.value, origin));
    if (previous_stamp >= 0) {
      const auto it = by_pair.find({previous_stamp, s.stamp_us});
      if (it != by_pair.end()) {
        OxfordPairError e;
        e.destination_stamp_us = previous_stamp;
        e.source_stamp_us = s.stamp_us;
        e.gt_x = it->second.x;
        e.gt_y = it->second.y;
        e.gt_yaw = it->second.yaw;
        e.est_x = step.relative.translation().x();
        e.est_y = -step.relative.translation().y();
        e.est_yaw = -std::atan2(step.relative.linear()(1, 0), step.relative.linear()(0, 0));
        e.translation_error = std::hypot(e.est_x - e.gt_x, e.est_y - e.gt_y);
        e.rotation_error = std::abs(std::remainder(e.est_yaw - e.gt_yaw, 2 * M_PI));
        e.estimated = step.ok;
        e.features = step.features;
        e.matches = step.matches;
        e.inliers = step.inliers;
        e.ms_features = step.ms_features;
        e.ms_matching = step.ms_matching;
        e.ms_motion = step.ms_motion;
        ev.pairs.push_back(e);
        auto pose2 = [](double x, double y, double yaw) {
          Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
          T.linear() = Eigen::Rotation2Dd(yaw).toRotationMatrix();
          T.translation() = Eigen::Vector2d(x, y);
          return T;
        };
        chained_est = chained_est * pose2(e.est_x, e.est_y, e.est_yaw);
        chained_gt = chained_gt * pose2(e.gt_x, e.gt_y, e.gt_yaw);
      }
    }
    previous_stamp = s.stamp_us;
  }
  if (ev.pairs.empty()) {
    ev.error += "no scan pair of " + drive_dir + " is in " + odometry_csv;
    return ev;
  }
  double sum_t = 0, sum_r = 0, sum_drift = 0;
  for (const OxfordPairError& e : ev.pairs) {
    const double length = std::hypot(e.gt_x, e.gt_y);
    ev.gt_length += length;
    sum_t += e.translation_error;
    sum_r += e.rotation_error;
    sum_drift += length > 1e-6 ? 100.0 * e.translation_error / length : 0.0;
    ev.max_translation_error = std::max(ev.max_translation_error, e.translation_error);
    ev.max_rotation_error_deg = std::max(ev.max_rotation_error_deg, e.rotation_error * 180 / M_PI);
  }
  const double n = double(ev.pairs.size());
  ev.mean_translation_error = sum_t / n;
  ev.mean_rotation_error_deg = sum_r / n * 180 / M_PI;
  ev.mean_pair_drift_percent = sum_drift / n;
  ev.drift_percent =
      100.0 * (chained_est.translation() - chained_gt.translation()).norm() / ev.gt_length;
  ev.ok = true;
  return ev;
}

}  // namespace osm_graph_slam::radar
