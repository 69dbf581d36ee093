#pragma once
// Spinning FMCW radar (Navtech CIR204-H as in MulRan) on the urban simulator's worlds and
// trajectories, written as a MulRan-layout drive (doc/radar.md): returns of building walls,
// cars, poles, trees, fences and the ground from a fan of rays per azimuth; receiver noise and
// speckle, multipath ghosts behind strong walls, saturation; every azimuth at its own time in the
// 0.25 s turn (motion skew) and its range shifted by the Doppler term of seed eq. 7.9.
// Seeded: the same seed gives byte-identical files.
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "osm_graph_slam/radar/radar_scan.h"
#include "osm_graph_slam/sim/simulator.h"

namespace osm_graph_slam::sim {

class SimRng;

struct NavtechModel {
  int azimuths = 400;                   ///< rows per turn (0.9 deg)
  int bins = 3360;                      ///< MulRan polar width
  double range_resolution = 0.0595238;  ///< [m/bin]
  double rotation_period = 0.25;        ///< [s] 4 Hz
  double mount_height = 1.0;            ///< [m] above base_link (~1.9 m above the ground)
  double doppler_beta = 0.049;          ///< [s] f_t/(df/dt); 0: no Doppler shift
  int max_scans = 0;                    ///< sweeps written (0: the whole route)
  bool motion_skew = true;              ///< false: the whole turn at the sweep's start pose
  // Beam: a fan of rays per azimuth (horizontal beam width 1.8 deg, vertical fan).
  double beam_width_deg = 1.8;
  int rays_across = 3;                                ///< across the horizontal width
  double elevations_deg[4] = {-2.0, -0.5, 1.0, 2.5};  ///< vertical fan
  // Power (8-bit, log scale as the sensor outputs it).
  double noise_mean = 10.0, noise_sigma = 4.0;  ///< receiver noise floor
  double peak_gain = 135.0;                     ///< power of reflectivity 1 at 10 m, normal
  double reflectivity_db = 40.0;                ///< per decade of reflectivity * cos(incidence)
  double range_db = 22.0;                       ///< loss per decade of range
  double speckle_sigma = 6.0;                   ///< per-ray power jitter
  double lobe_sigma = 0.12;                     ///< [m] range lobe of a point return
  int saturation = 200;                         ///< powers clip here
  double ghost_probability = 0.04;              ///< multipath ghost behind a wall hit
  double ghost_loss = 30.0;                     ///< ghost power below the wall's
};

struct RadarDriveStats {
  size_t scans = 0, gps = 0, imu = 0, poses = 0;
  double route_length_m = 0, duration_s = 0;
  double mean_hits_per_scan = 0;
  double generation_s = 0, scans_per_s = 0;
  std::string drive_dir;
};

class RadarSimulator {
 public:
  RadarSimulator(const UrbanSimulator& world, const NavtechModel& model, uint64_t seed)
      : sim_(world), model_(model), seed_(seed) {}

  size_t numScans() const;
  /// Start time of sweep k [s since the drive's start].
  double sweepStart(size_t k) const { return double(k) * model_.rotation_period; }
  /// Radar pose in ENU at time t (base_link raised by mount_height; planar radar frame =
  /// base_link's x forward, y left).
  Eigen::Isometry3d radarPose(double t) const;
  /// Linear velocity of the radar in its own frame at t [m/s].
  Eigen::Vector3d radarVelocity(double t) const;
  /// Sweep k (times relative to the drive's start). hits: ray returns placed.
  radar::RadarPolarScan simulate(size_t k, size_t* hits = nullptr) const;
  /// MulRan layout below out_dir: global_pose.csv, sensor_data/{data_stamp,gps,xsens_imu}.csv,
  /// sensor_data/radar/polar/<stamp_ns>.png.
  bool writeMulranDrive(const std::string& out_dir, RadarDriveStats& stats,
                        const std::function<void(size_t, size_t)>& progress = {},
                        std::string* error = nullptr) const;

 private:
  /// xsens_imu.csv rows at 100 Hz from LiDAR epoch k (time t, measured record meas) to the next.
  std::string imuRows(size_t k, double t, const OxtsRecord& meas, double end_time,
                      const std::function<int64_t(double)>& stamp_of, SimRng& rng,
                      std::map<int64_t, std::vector<std::string>>& events,
                      RadarDriveStats& stats) const;

  const UrbanSimulator& sim_;
  NavtechModel model_;
  uint64_t seed_;
};

}  // namespace osm_graph_slam::sim
