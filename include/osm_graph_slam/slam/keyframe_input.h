#pragma once
// The back-end's keyframe input: built from the tracker's keyframe (one builder for the offline
// pipeline and the scan_matching -> graph_backend message), and aided by what the IMU/INS and
// GNSS said at its stamp, which also decides the first keyframe's heading (KeyframeAiding). One
// owner for the graph_backend nodelet and the offline runners (SlamPipeline), in the manner of
// Cartographer's SensorBridge feeding its core. The runners only feed what their sensors said:
// the nodelet its imu/data and gps/fix messages (sensors(), matched here by time), the offline
// runners what the drive recorded at each scan (ScanAiding).
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/sensor_inputs.h"

namespace osm_graph_slam {

/// What the IMU/INS and GNSS said at one stamp.
struct ScanAiding {
  /// base_link roll and pitch against gravity from an IMU [rad] (attitude priors).
  std::optional<Eigen::Vector2d> gravity_roll_pitch;
  /// base_link's GNSS position in the map frame [m] (the first keyframe is placed there; with
  /// gnss_prior_std > 0 every keyframe gets a prior).
  std::optional<Eigen::Vector2d> gnss_position;
  /// That fix's horizontal standard deviation [m], when the receiver reports it.
  std::optional<double> gnss_std;
  /// Its altitude in the map frame (up from the map origin) [m], if known.
  std::optional<double> gnss_altitude;
  /// base_link's orientation in ENU from an IMU/INS: the tracker's imu guesses use its change
  /// between scans, and with ins_heading_std > 0 its yaw is a heading prior on keyframes.
  std::optional<Eigen::Quaterniond> imu_orientation;
};

/// The first keyframe's heading and where it came from.
struct FirstHeading {
  std::optional<double> yaw;  ///< ENU yaw of base_link; none: the first OSM global matching
  bool from_imu = false;      ///< decided from the IMU now (else known before the drive, or none)
  std::string warning;        ///< one line to log when not empty
};

class KeyframeAiding {
 public:
  /// known_initial_yaw: a heading known before the drive (the initial_yaw parameter, or the
  /// drive's own start heading given to an offline runner); it wins over the IMU.
  /// heading_from_imu: without a known heading, the IMU's at the first keyframe decides it.
  /// keep_fixes: every keyframe's fix is wanted (GNSS priors); otherwise the buffered fixes are
  /// forgotten once the first keyframe has its fix (it anchors the map).
  KeyframeAiding(const SensorInputsParams& params, std::optional<double> known_initial_yaw,
                 bool heading_from_imu, bool keep_fixes);

  /// The buffers the nodelet feeds (addOrientation, addFix, setOrigin).
  SensorInputs& sensors() { return sensors_; }
  const SensorInputs& sensors() const { return sensors_; }

  /// What the buffered samples say at stamp.
  ScanAiding at(double stamp) const;

  /// Fills kf's attitude, INS yaw and GNSS fields from what the sensors said at its stamp. The
  /// first keyframe also decides the heading: the known one, else (heading_from_imu) the IMU's at
  /// its stamp, else the newest buffered sample at most initial_heading_max_age before it, else
  /// none (global matching against the OSM buildings sets it). Returned for the first only.
  std::optional<FirstHeading> aid(const ScanAiding& sensors, KeyframeInput& kf);

 private:
  FirstHeading decideFirstHeading(const ScanAiding& sensors, double stamp) const;

  SensorInputs sensors_;
  std::optional<double> known_initial_yaw_;
  bool heading_from_imu_;
  bool keep_fixes_;
  bool first_seen_ = false;
};

/// The back-end's input for a keyframe the tracker made (without the sensors' aiding): the
/// match's fitness, Hessian and prediction error when it converged, else unknown.
KeyframeInput keyframeInput(const Keyframe& kf, const TrackResult& track);

}  // namespace osm_graph_slam
