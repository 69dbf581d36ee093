#pragma once
// Radar SLAM on a live stream of polar images (the core of the radar_odometry nodelet,
// doc/radar.md "ROS: radar_odometry nodelet and radar.launch", "Radar SLAM through ROS"): each
// image is checked against the layout and converted (fromMulranImage), a stamp not newer than the
// last sweep's is dropped, a gap longer than max_gap restarts the odometry (velocity zero, no
// matching across the gap, the pose kept, the graph kept), and everything dropped or restarted is
// counted. The sweeps go through RadarSlam (radar_slam.h): the odometry, and with loop/enabled
// the keyframe graph with its loop closures; without loops the result is the odometry's.
#include <cstdint>
#include <string>

#include <Eigen/Geometry>

#include "osm_graph_slam/radar/radar_odometry.h"
#include "osm_graph_slam/radar/radar_scan.h"
#include "osm_graph_slam/radar/radar_slam.h"

namespace osm_graph_slam {
class ParamReader;
namespace radar {

struct RadarStreamParams {
  MulranPolarLayout layout;  ///< expected rows / columns, range resolution, rotation period
  double max_gap = 2.0;      ///< [s] between sweep stamps (8 sweeps at 4 Hz); longer: restart
};

/// Reads "input/azimuths", "input/bins", "input/range_resolution", "input/rotation_period",
/// "input/max_gap" (config/radar.yaml). False with the reason for a non-positive value.
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
  int new_loops = 0;  ///< loops accepted on this sweep: the corrected past has moved
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
  RadarSlam slam_;
  bool loops_enabled_;
  RadarStreamParams params_;
  RadarStreamCounters counters_;
  bool has_last_ = false;
  int64_t last_stamp_ns_ = 0;
  int64_t origin_ns_ = 0;  ///< the first sweep's stamp: the odometry runs on times relative to it
};

}  // namespace radar
}  // namespace osm_graph_slam
