#pragma once
// GNSS/INS error models of the urban simulator: what a consumer-grade GNSS receiver with a MEMS
// IMU reports instead of the true pose (white noise, a slowly varying Gauss-Markov bias and
// outages of the fix; attitude noise, a constant heading bias per drive, gyro and accelerometer
// noise). With rtk every error is zero and the records are the true ones (an RTK-corrected OXTS
// RT3003 as in KITTI). The canyon model (gnss_model kCanyon, sim/gnss_canyon.h) replaces the
// GNSS part by the fixes of a receiver among the true buildings and keeps the INS part. See
// doc/simulator.md, "GNSS/INS error models" and "Urban-canyon GNSS model".
#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/sim/gnss_canyon.h"

namespace osm_graph_slam {
class EnuConverter;
}

namespace osm_graph_slam::sim {

/// Where the GNSS fixes come from when not rtk (simulate_urban --gnss-model).
enum class GnssPositionModel : uint8_t {
  kNoisy,   ///< white noise + Gauss-Markov bias + Poisson outages, whatever the city
  kCanyon,  ///< from the satellites the true buildings let through (sim/gnss_canyon.h)
};

/// One place of defaults: consumer-grade GNSS + MEMS IMU (the simulate_urban default).
struct NavErrorParams {
  bool rtk = false;  ///< exact GNSS/INS (RTK, KITTI-like): every field below is ignored
  GnssPositionModel gnss_model = GnssPositionModel::kNoisy;
  CanyonGnssParams canyon;  ///< with gnss_model kCanyon (the gnss_* fields are then unused)

  double gnss_sigma = 1.5;                ///< white noise per horizontal axis [m]
  double gnss_sigma_vertical = 2.5;       ///< white noise, up [m]
  double gnss_bias_sigma = 1.0;           ///< Gauss-Markov bias per horizontal axis [m]
  double gnss_bias_sigma_vertical = 1.5;  ///< Gauss-Markov bias, up [m]
  double gnss_bias_tau_s = 90.0;          ///< correlation time of the bias [s]
  double gnss_outages_per_km = 0.5;       ///< Poisson rate of outage starts along the path
  double gnss_outage_duration_s = 20.0;   ///< each outage [s]
  /// No outage starts earlier: the first fix is the map origin (a drive needs one).
  double gnss_outage_min_start_s = 10.0;

  double imu_attitude_sigma_deg = 0.05;  ///< roll and pitch white noise [deg]
  /// Magnitude of a constant yaw bias per drive [deg]; its sign is drawn from the seed.
  double imu_heading_bias_deg = 0.3;
  double imu_heading_sigma_deg = 0.1;  ///< yaw white noise on top of the bias [deg]
  double gyro_sigma_deg_s = 0.1;       ///< white noise on the angular rates [deg/s]
  /// Magnitude of a constant bias of the yaw-rate gyro per drive [deg/s]; its sign is drawn from
  /// the seed. 0 keeps the LiDAR drives as they were; a MEMS IMU has 0.001-0.01 deg/s in run.
  double gyro_bias_deg_s = 0.0;
  double accel_sigma = 0.05;  ///< white noise on the accelerations [m/s^2]
};

/// The errors of one OXTS record (one epoch).
struct NavEpochError {
  Eigen::Vector3d gnss = Eigen::Vector3d::Zero();       ///< ENU position error: white + bias [m]
  Eigen::Vector3d gnss_bias = Eigen::Vector3d::Zero();  ///< its Gauss-Markov part [m]
  bool outage = false;                                  ///< no fix in this record
  double roll = 0.0, pitch = 0.0, yaw = 0.0;            ///< attitude errors [rad]; yaw incl. bias
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();       ///< body rate noise [rad/s]
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();      ///< body acceleration noise [m/s^2]
  /// The canyon model's own report with its fix (pos_accuracy [m], satellites used); NaN and
  /// -1 in the noisy model, whose report is the same every epoch (gnssReportedAccuracy).
  double reported_accuracy = std::numeric_limits<double>::quiet_NaN();
  int satellites_used = -1;
};

struct NavErrorSequence {
  std::vector<NavEpochError> epochs;
  double heading_bias = 0.0;  ///< [rad]
  double gyro_bias_z = 0.0;   ///< [rad/s], in every epoch's gyro.z()
  int outages = 0;            ///< outages that start within the epochs
};

/// Errors of epochs k = 0..path_length.size()-1 at times k * dt; path_length[k] is the distance
/// driven at epoch k [m] (outages are a Poisson process along the path). Deterministic in seed;
/// independent random streams per error kind, so changing one parameter leaves the others'
/// draws as they were. With rtk every error is zero.
NavErrorSequence simulateNavErrors(const NavErrorParams& params, uint64_t seed, double dt,
                                   const std::vector<double>& path_length);

/// Sets rtk / gnss_model from "noisy", "rtk" or "canyon"; false for another name.
bool parseGnssModel(const std::string& name, NavErrorParams& params);
/// "rtk", "noisy" or "canyon".
const char* gnssModelName(const NavErrorParams& params);

/// The canyon receiver's fixes as the GNSS part of the sequence (the INS part stays): error =
/// fix - truth, outage where there is no fix, pos_accuracy per axis = the reported horizontal
/// accuracy / sqrt(2) (kitti2bag's covariance is per axis), satellites used.
void applyCanyonFixes(const std::vector<CanyonEpoch>& fixes, NavErrorSequence& sequence);

/// pos_accuracy of a record with a fix: the horizontal sigma per axis of white noise and bias
/// together (kitti2bag turns it into the NavSatFix covariance).
double gnssReportedAccuracy(const NavErrorParams& params);

/// The record the GNSS/INS reports: `truth` with the epoch's attitude and IMU errors and its
/// position replaced by fix_enu (the measured fix, ENU of enu). For an outage fix_enu is the last
/// fix (held), pos_accuracy = kOxtsNoFixAccuracy and numsats = posmode = velmode = 0. With rtk,
/// truth itself.
OxtsRecord measuredOxtsRecord(const OxtsRecord& truth, const Eigen::Vector3d& fix_enu,
                              const NavEpochError& error, const NavErrorParams& params,
                              const EnuConverter& enu);

}  // namespace osm_graph_slam::sim
