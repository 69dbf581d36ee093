#pragma once
// Radar SLAM on a live stream of polar images (the core of the radar_odometry nodelet,
// doc/radar.md "ROS: radar_odometry nodelet and radar.launch", "Radar SLAM through ROS"): each
// image is checked against the layout and converted (fromMulranImage), a stamp not newer than the
// last sweep's is dropped, a gap longer than max_gap restarts the odometry (velocity zero, no
// matching across the gap, the pose kept, the graph kept), and everything dropped or restarted is
// counted. The sweeps go through RadarSlam (radar_slam.h): the odometry, and with loop/enabled
// the keyframe graph with its loop closures; without loops the result is the odometry's.
// With loops the stream also takes GNSS fixes and gyro yaw rates (gps/fix, imu/data): fixes in
// ENU around the first valid fix, both on the sweeps' clock, those before the first sweep held
// for it (doc/radar.md "GNSS and gyro through ROS").
#include <cstdint>
#include <deque>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "osm_graph_slam/osm/enu_converter.h"

#include "osm_graph_slam/radar/radar_odometry.h"
#include "osm_graph_slam/radar/radar_scan.h"
#include "osm_graph_slam/radar/radar_slam.h"

namespace osm_graph_slam {
class ParamReader;
namespace radar {

struct RadarStreamParams {
  MulranPolarLayout layout;  ///< expected rows / columns, range resolution, rotation period
  double max_gap = 2.0;      ///< [s] between sweep stamps (8 sweeps at 4 Hz); longer: restart
  /// [m] horizontal sigma given to a fix without a covariance (NavSatFix COVARIANCE_TYPE_UNKNOWN:
  /// a negative or NaN sigma); above gnss/max_sigma such fixes would be rejected.
  double gnss_unknown_sigma = 5.0;
  /// [s] fixes and yaw rates that arrive before the first sweep are held for it (at most 4096,
  /// the newest) and handed over when it comes, but for those stamped more than nav_buffer before
  /// it: dropped and counted (the first keyframe interpolates between the fixes around it).
  double nav_buffer = 1.0;
};

/// Reads "input/azimuths", "input/bins", "input/range_resolution", "input/rotation_period",
/// "input/max_gap", "input/gnss_unknown_sigma", "input/nav_buffer" (config/radar.yaml). False
/// with the reason for a non-positive value (nav_buffer: negative).
bool readParams(const ParamReader& reader, RadarStreamParams& params, std::string* error);

enum class RadarStreamEvent {
  kProcessed,   ///< the sweep went through the odometry (and the back-end)
  kRestarted,   ///< processed as a first sweep after a gap (velocity reset to zero)
  kBadImage,    ///< dropped: empty, wrong encoding or size, too few bytes
  kOutOfOrder,  ///< dropped: stamp not newer than the last processed sweep's
};
const char* toString(RadarStreamEvent event);

struct RadarStreamCounters {
  uint64_t received = 0, processed = 0;
  uint64_t bad_images = 0, out_of_order = 0, gaps = 0;
  uint64_t ransac_failures = 0;  ///< sweeps whose velocity was not estimated (constant velocity)
  double ms_last = 0.0;  ///< [ms] conversion + odometry + back-end of the last processed sweep
  double ms_mean = 0.0;  ///< [ms] mean over the processed sweeps
  /// [ms] loop search, verification and optimisation per keyframe searched (RadarLoopStats).
  double ms_loop_per_keyframe = 0.0;
  // Navigation input (addGnssFix, addYawRate); what the back-end does with it: RadarNavStats.
  uint64_t gnss_received = 0;       ///< fixes given to the stream
  uint64_t gnss_invalid = 0;        ///< no fix (status), NaN or out-of-range position: not used
  uint64_t gnss_unknown_sigma = 0;  ///< used with gnss_unknown_sigma (no covariance)
  uint64_t imu_received = 0;        ///< yaw rates given to the stream
  uint64_t imu_invalid = 0;         ///< rate not available (REP-145) or NaN: not used
  uint64_t nav_buffered = 0;        ///< held before the first sweep and handed over with it
  uint64_t nav_dropped_early = 0;   ///< more than nav_buffer older than the first sweep
  uint64_t nav_ignored = 0;         ///< given to a stream without loops (pure odometry)
};

struct RadarStreamResult {
  RadarStreamEvent event = RadarStreamEvent::kBadImage;
  std::string message;    ///< why the image was dropped or the odometry restarted
  bool has_step = false;  ///< kProcessed or kRestarted
  RadarOdometryStep step;
  int64_t time_ns = 0;  ///< the step's reference (mid) time on the input clock [ns]
  /// The map -> odometry correction after this sweep (RadarSlam::mapToOdometry; identity
  /// without loops) and the sweep's pose in the map frame (= correction * step.pose).
  Eigen::Isometry2d map_to_odometry = Eigen::Isometry2d::Identity();
  Eigen::Isometry2d corrected = Eigen::Isometry2d::Identity();
  int new_loops = 0;        ///< loops accepted on this sweep: the corrected past has moved
  bool new_anchor = false;  ///< the GNSS anchor (RadarSlam::mapFromEnu) was set on this sweep
  /// The graph was optimised on this sweep (a loop, the anchor, GNSS edges): the corrected past
  /// (RadarSlam::sweepPoses) has moved.
  bool optimised = false;
  explicit operator bool() const { return has_step; }
};

class RadarOdometryStream {
 public:
  RadarOdometryStream(const RadarSlamParams& slam, const RadarStreamParams& stream)
      : slam_(slam), loops_enabled_(slam.loop.enabled), params_(stream) {}
  /// Pure odometry (loop/enabled false).
  RadarOdometryStream(const RadarOdometryParams& odometry, const RadarStreamParams& stream)
      : RadarOdometryStream(odometryOnly(odometry), stream) {}
  /// One image with its stamp (the start of the sweep) [ns].
  RadarStreamResult process(const PolarImageView& image, int64_t stamp_ns);
  /// A GNSS fix at stamp_ns (input clock) [WGS84 deg, m]; sigma: horizontal, per axis [m]
  /// (negative or NaN: unknown, params().gnss_unknown_sigma is used); valid: the receiver has a
  /// fix (false for NavSatFix STATUS_NO_FIX). A valid fix with a finite position goes to
  /// RadarSlam::addGnssFix in ENU around the first such fix (a NaN altitude: the origin's), the
  /// others are counted (gnss_invalid). Only with loops; give the data in stamp order per source
  /// before the sweeps it covers (the back-end counts and drops older ones).
  void addGnssFix(int64_t stamp_ns, double lat, double lon, double alt, double sigma,
                  bool valid = true);
  /// A yaw rate about the vehicle's up axis [rad/s] at stamp_ns; available false (REP-145: an
  /// Imu without rates) or a NaN rate: counted (imu_invalid), not used. Only with loops.
  void addYawRate(int64_t stamp_ns, double rate, bool available = true);
  /// The end of the input (RadarSlam::finish): the keyframes still waiting for navigation data
  /// are decided and the graph is optimised. The nodelet never ends its input; tools and tests do.
  void finish() { slam_.finish(); }
  /// The ENU frame of the fixes (origin: the first valid fix), once there is one.
  const std::optional<EnuConverter>& enu() const { return enu_; }
  const RadarStreamCounters& counters() const { return counters_; }
  const RadarStreamParams& params() const { return params_; }
  const RadarSlam& slam() const { return slam_; }
  bool loopsEnabled() const { return loops_enabled_; }
  /// A time of the back-end (RadarSlam::sweepTimes: seconds since the first sweep's stamp) on
  /// the input clock [ns].
  int64_t toInputTime(double time) const;

 private:
  static RadarSlamParams odometryOnly(const RadarOdometryParams& odometry) {
    RadarSlamParams p;
    p.odometry = odometry;
    p.loop.enabled = false;
    return p;
  }
  /// A fix (x, y, sigma in ENU) or a yaw rate (rate, 0, 0) before the first sweep.
  struct PendingNav {
    int64_t stamp_ns = 0;
    bool fix = false;
    Eigen::Vector3d value = Eigen::Vector3d::Zero();
  };
  void handOver(const PendingNav& nav);
  void holdForFirstSweep(const PendingNav& nav);

  RadarSlam slam_;
  bool loops_enabled_;
  RadarStreamParams params_;
  RadarStreamCounters counters_;
  bool has_last_ = false;
  int64_t last_stamp_ns_ = 0;
  int64_t origin_ns_ = 0;  ///< the first sweep's stamp: the odometry runs on times relative to it
  std::optional<EnuConverter> enu_;
  std::deque<PendingNav> pending_;  ///< in arrival order, until the first sweep (at most 4096)
};

}  // namespace radar
}  // namespace osm_graph_slam
