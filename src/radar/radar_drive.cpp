#include "osm_graph_slam/radar/radar_drive.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>

#include "osm_graph_slam/common/timing.h"
#include "osm_graph_slam/io/mulran.h"
#include "osm_graph_slam/osm/enu_converter.h"

namespace osm_graph_slam::radar {
namespace {

// A sweep sees the navigation data up to half a second past its first azimuth (it lasts 0.25 s).
constexpr int64_t kNavLookaheadNs = 500'000'000;

/// gps.csv (in ENU around the first fix) and the xsens yaw rate, fed to the SLAM in time order.
class NavigationFeed {
 public:
  NavigationFeed(const MulranSequence& seq, int64_t origin_ns) : seq_(seq), origin_ns_(origin_ns) {
    if (!seq.gps.empty())
      enu_.emplace(seq.gps.front().lat, seq.gps.front().lon, seq.gps.front().alt);
  }
  void feedUntil(int64_t stamp_ns, RadarSlam& slam) {
    for (; gps_ < seq_.gps.size() && seq_.gps[gps_].stamp_ns <= stamp_ns; ++gps_) {
      const MulranGps& g = seq_.gps[gps_];
      const double sigma = std::sqrt(std::max(g.covariance[0], g.covariance[4]));
      slam.addGnssFix(seconds(g.stamp_ns), enu_->toEnu(g.lat, g.lon, g.alt).head<2>(), sigma);
    }
    for (; imu_ < seq_.imu.size() && seq_.imu[imu_].stamp_ns <= stamp_ns; ++imu_)
      if (seq_.imu[imu_].has_rates)
        slam.addYawRate(seconds(seq_.imu[imu_].stamp_ns), seq_.imu[imu_].gyro.z());
  }

 private:
  double seconds(int64_t stamp_ns) const { return double(stamp_ns - origin_ns_) * 1e-9; }
  const MulranSequence& seq_;
  int64_t origin_ns_;
  std::optional<EnuConverter> enu_;
  size_t gps_ = 0, imu_ = 0;
};

}  // namespace

Eigen::Isometry3d planarTo3d(const Eigen::Isometry2d& T) {
  Eigen::Isometry3d P = Eigen::Isometry3d::Identity();
  P.linear().topLeftCorner<2, 2>() = T.linear();
  P.translation().head<2>() = T.translation();
  return P;
}

RadarDriveResult runMulranRadarSlam(
    const std::string& root, const RadarSlamParams& params, const RadarDriveOptions& options,
    const std::function<void(const RadarOdometryStep&, const RadarPolarScan&)>& on_step) {
  RadarDriveResult result;
  MulranSequence seq;
  if (!readMulranSequence(root, seq, &result.error)) return result;
  std::vector<int64_t> stamps;
  for (const MulranStamp& s : seq.stamps)
    if (s.sensor == "radar") stamps.push_back(s.stamp_ns);
  if (stamps.empty()) {
    result.error = "MulRan sequence '" + root + "' lists no radar sweep in data_stamp.csv";
    return result;
  }
  const int64_t origin_ns = stamps.front();
  Trajectory truth;  // global_pose.csv, times relative to origin
  for (const MulranPose& p : seq.poses)
    truth.push_back({double(p.stamp_ns - origin_ns) * 1e-9, p.pose});
  const double max_gap = 1.0;  // [s] ground truth further away is not interpolated
  Eigen::Isometry3d first_truth_inverse = Eigen::Isometry3d::Identity();
  bool have_first_truth = false;
  RadarSlam slam(params);
  NavigationFeed nav(seq, origin_ns);
  using Clock = std::chrono::steady_clock;
  double first_time = 0, last_time = 0;
  for (int64_t stamp : stamps) {
    if (options.max_scans > 0 && result.scans >= options.max_scans) break;
    nav.feedUntil(stamp + kNavLookaheadNs, slam);
    const auto t0 = Clock::now();
    MulranPolarResult read =
        readMulranPolarPng(seq.radarPolarPath(stamp), stamp, origin_ns, options.layout);
    if (!read.ok) {
      result.skipped.push_back(read.error);
      continue;
    }
    result.ms_read += msSince(t0);
    RadarOdometryStep step = slam.process(read.scan);
    if (on_step) on_step(step, read.scan);
    step.feature_set = RadarFeatureSet();
    if (result.scans == 0) first_time = step.time;
    last_time = step.time;
    ++result.scans;
    if (!step.ok) ++result.failed;
    result.ms_features += step.ms_features;
    result.ms_matching += step.ms_matching;
    result.ms_motion += step.ms_motion;
    result.ms_registration += step.ms_registration;
    if (step.registered) ++result.registered;
    const double absolute = double(origin_ns) * 1e-9 + step.time;
    result.odometry.push_back({absolute, planarTo3d(step.pose)});
    Eigen::Isometry3d gt;
    if (interpolatePose(truth, step.time, max_gap, gt)) {
      if (!have_first_truth) {
        first_truth_inverse = gt.inverse();
        have_first_truth = true;
      }
      result.ground_truth.push_back({absolute, first_truth_inverse * gt});
    }
    result.steps.push_back(std::move(step));
  }
  if (result.scans == 0) {
    result.error = "no radar sweep of '" + root + "' could be read";
    return result;
  }
  nav.feedUntil(INT64_MAX, slam);
  slam.finish();
  result.nav_stats = slam.navStats();
  const std::vector<Eigen::Isometry2d> corrected = slam.sweepPoses();
  for (size_t i = 0; i < corrected.size() && i < result.odometry.size(); ++i)
    result.trajectory.push_back({result.odometry[i].stamp, planarTo3d(corrected[i])});
  result.loops = slam.loops();
  result.loop_stats = slam.loopStats();
  result.keyframes = slam.numKeyframes();
  const double n = result.scans;
  result.ms_read /= n;
  result.ms_features /= n;
  result.ms_matching /= n;
  result.ms_motion /= n;
  result.ms_registration /= n;
  result.span_s = last_time - first_time;
  result.ok = true;
  return result;
}

}  // namespace osm_graph_slam::radar
