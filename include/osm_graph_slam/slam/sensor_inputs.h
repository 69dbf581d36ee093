#pragma once
// IMU attitude and GNSS fixes buffered by time and matched to keyframes, and the first
// keyframe's heading policy: one core class for the graph_backend nodelet and the offline drive
// readers, so that ROS and offline runs place the first keyframe the same way. Thread-safe.
#include <Eigen/Geometry>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/gnss_fix_lookup.h"
#include "osm_graph_slam/slam/sensor_inputs_params.h"

namespace osm_graph_slam {

/// An IMU / INS orientation of base_link in ENU.
struct AttitudeSample {
  double stamp = 0.0;  ///< [s]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  double roll = 0.0, pitch = 0.0, yaw = 0.0;  ///< R = Rz(yaw) Ry(pitch) Rx(roll)
};

/// A GNSS position in the map frame (ENU at the origin).
struct GnssPosition {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double std_xy = 0.0;             ///< [m] the fix's reported horizontal deviation (0: unknown)
  std::optional<double> altitude;  ///< [m] up from the origin, if the fix has an altitude
};

/// The first keyframe's heading and, when it is not the sample at the keyframe's stamp, why.
struct InitialHeading {
  std::optional<double> yaw;  ///< ENU yaw of base_link; none: the IMU cannot say
  std::string warning;        ///< one line to log when not empty
};

class SensorInputs {
 public:
  explicit SensorInputs(const SensorInputsParams& params = {});

  const SensorInputsParams& params() const { return params_; }

  /// False (and nothing kept) for a non-finite or zero quaternion.
  bool addOrientation(double stamp, const Eigen::Quaterniond& orientation);
  /// False (and nothing kept) for non-finite coordinates. Kept in stamp order, whatever order
  /// the fixes arrive in.
  bool addFix(const GnssFixSample& fix);
  /// Forgets the fixes and keeps no later one (a drive that needs only the first keyframe's).
  void stopKeepingFixes();
  /// The map origin: GNSS positions are in ENU at it. Until then gnssPositionAt() gives none.
  /// alt NaN: unknown (the fixes' altitudes are then not used).
  void setOrigin(double lat, double lon, double alt = std::numeric_limits<double>::quiet_NaN());

  /// The sample nearest to stamp, if one is within imu_max_time_difference.
  std::optional<AttitudeSample> attitudeAt(double stamp) const;
  /// The newest sample at most max_age before stamp.
  std::optional<AttitudeSample> latestAttitudeBefore(double stamp, double max_age) const;
  std::optional<AttitudeSample> firstAttitude() const;
  /// The fix at stamp (gnssFixAt: interpolated within gnss_max_gap, else the nearest within
  /// gnss_max_time_difference).
  std::optional<GnssFixSample> fixAt(double stamp) const;
  /// fixAt() in the map frame, once the origin is set.
  std::optional<GnssPosition> gnssPositionAt(double stamp) const;
  size_t numAttitudes() const;
  size_t numFixes() const;

  /// The first keyframe's heading (ART-SLAM's initial orientation): the IMU's at its stamp, else
  /// the newest sample at most initial_heading_max_age before it (its first scan was lost at
  /// start-up, or the drive has one sample at its first scan), else none.
  InitialHeading initialHeading(double stamp) const;

 private:
  SensorInputsParams params_;
  mutable std::mutex mutex_;
  std::deque<AttitudeSample> attitudes_;  ///< in stamp order
  std::vector<GnssFixSample> fixes_;      ///< in stamp order
  bool keep_fixes_ = true;
  std::optional<EnuConverter> enu_;
  bool altitude_known_ = false;  ///< the origin has an altitude (else fixes hold x and y only)
  double origin_altitude_ = 0.0;
};

}  // namespace osm_graph_slam
