#pragma once
// The urban drive simulator: world (OSM extract or procedural city) + route + LiDAR, written as a
// KITTI raw drive with ground truth and a perturbed OSM prior (see doc/simulator.md).
#include <Eigen/Geometry>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/sim/lidar.h"
#include "osm_graph_slam/sim/nav_errors.h"
#include "osm_graph_slam/sim/prior_map.h"
#include "osm_graph_slam/sim/route.h"
#include "osm_graph_slam/sim/scene.h"

namespace osm_graph_slam {
class EnuConverter;
}

namespace osm_graph_slam::sim {

/// Scans missing from the written drive, as in a bag that lost some (none by default). A dropped
/// scan has no .bin, no OXTS record, no timestamp line and no ground-truth row: the files stay
/// consecutively numbered and the stamps show the gap. The first scan is always kept.
struct ScanDropParams {
  double fraction = 0.0;  ///< each scan dropped independently with this probability
  int burst_length = 0;   ///< N consecutive scans missing (0: no burst)
  /// [s] since the start; NaN: a seeded time in the middle (30-70 %) of the drive.
  double burst_time = std::numeric_limits<double>::quiet_NaN();
};

struct SimulationParams {
  uint64_t seed = 1;
  /// The world's own seed (the procedural city's layout, every building's height); 0: seed.
  /// Two drives with the same world_seed and different seeds take other routes through the same
  /// world (a map drive and a drive to localise on it), each with its own clutter and noise.
  uint64_t world_seed = 0;
  /// The prior map's seed (its perturbation: errors, removed and phantom buildings); 0: seed.
  /// Drives of one world that share it share one prior map, as a fleet shares one OSM.
  uint64_t prior_seed = 0;
  std::string osm_path;  ///< empty: procedural city
  /// ENU origin. NaN: for an OSM extract the centre of its buildings' bounding box (a point of
  /// the extract), for the procedural city Karlsruhe (49.0110, 8.4170).
  double origin_lat = std::numeric_limits<double>::quiet_NaN();
  double origin_lon = std::numeric_limits<double>::quiet_NaN();
  double origin_alt = 115.0;
  CityParams city;
  ClutterParams clutter;
  bool clutter_enabled = true;
  /// A level ground (z = 0) instead of the gently sloped GroundModel: floor constraints must do
  /// no harm where there is no slope to find (issue 19).
  bool flat_ground = false;
  RouteParams route;
  LidarModel lidar = LidarModel::hdl64e();
  bool motion_distortion = false;
  /// With motion_distortion: points moved to the stamp's frame by the true motion (a perfectly
  /// compensating driver), instead of left in their column's frame as a raw driver does.
  bool compensated_sweep = false;
  PriorPerturbationParams prior;
  /// GNSS/INS errors of the oxts/ records (default consumer-grade; nav.rtk = true: exact).
  NavErrorParams nav;
  ScanDropParams scan_drop;
  int max_scans = 0;                                    ///< 0: the whole route
  StampNs start_time_ns = 1577880000LL * 1000000000LL;  ///< 2020-01-01 12:00:00 UTC
  int drive_number = 1;
};

struct SimulationStats {
  size_t buildings = 0, primitives = 0, moving_objects = 0, walls = 0;
  size_t scans = 0;  ///< written (numScans() minus the dropped ones)
  size_t dropped_scans = 0;
  double route_length_m = 0, duration_s = 0;
  int revisits = 0;
  double max_yaw_rate_deg_s = 0, max_lateral_accel = 0;
  double mean_points_per_scan = 0, min_points_per_scan = 0, max_points_per_scan = 0;
  double building_fraction = 0, ground_fraction = 0, clutter_fraction = 0, moving_fraction = 0;
  double generation_s = 0, raycast_s = 0, scans_per_s = 0;
  size_t prior_perturbed = 0, prior_removed = 0, prior_phantom = 0;
  /// Over the written records with a fix: horizontal GNSS error RMS and max [m]; outages.
  double gnss_error_rms_m = 0, gnss_error_max_m = 0;
  int gnss_outages = 0;
  double gnss_outage_s = 0;
  CanyonDriveStats canyon;  ///< with the canyon GNSS model: the receiver over the scans' epochs
  std::string drive_dir;
};

class UrbanSimulator {
 public:
  UrbanSimulator();
  ~UrbanSimulator();
  /// Builds world, route and trajectory. False with a reason (bad OSM file, no drivable loop).
  bool build(const SimulationParams& params, std::string* error = nullptr);

  const Scene& scene() const { return scene_; }
  const Trajectory& trajectory() const { return trajectory_; }
  const Route& route() const { return route_; }
  const SimulationParams& params() const { return params_; }
  const EnuConverter& enu() const { return *enu_; }
  size_t numScans() const;
  /// Per scan of numScans(): true if it is left out of the written drive (params().scan_drop).
  std::vector<bool> droppedScans() const;
  double scanTime(size_t k) const { return double(k) / params_.lidar.rate_hz; }

  /// base_link (= IMU / OXTS frame, as in KITTI raw) pose in ENU at time t since start.
  Eigen::Isometry3d basePose(double t) const;
  /// LiDAR (velo_link) pose in ENU.
  Eigen::Isometry3d sensorPose(double t) const { return basePose(t) * T_imu_velo_; }
  /// p_velo = T_velo_imu * p_imu (calib_imu_to_velo.txt).
  const Eigen::Isometry3d& T_velo_imu() const { return T_velo_imu_; }
  /// The true OXTS record at time t (written to oxts_true/).
  OxtsRecord oxtsAt(double t) const;
  /// What the GNSS/INS reports at scan k (written to oxts/): oxtsAt with params().nav's errors.
  OxtsRecord measuredOxts(size_t k) const;
  /// The GNSS/INS errors of every scan of the route (all zero with nav.rtk).
  const NavErrorSequence& navErrors() const { return nav_errors_; }
  /// The canyon receiver's output at every scan of the route (empty unless that model is used).
  const std::vector<CanyonEpoch>& canyonFixes() const { return canyon_fixes_; }

  SimulatedScan simulate(size_t k) const;

  /// Writes the whole dataset below out_dir (see doc/simulator.md for the layout).
  bool writeDataset(const std::string& out_dir, SimulationStats& stats,
                    const std::function<void(size_t, size_t)>& progress = {},
                    std::string* error = nullptr) const;

 private:
  SimulationParams params_;
  Scene scene_;
  Route route_;
  Trajectory trajectory_;
  std::unique_ptr<EnuConverter> enu_;
  NavErrorSequence nav_errors_;
  std::vector<CanyonEpoch> canyon_fixes_;
  Eigen::Isometry3d T_velo_imu_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_imu_velo_ = Eigen::Isometry3d::Identity();

  /// The canyon receiver at every epoch of the route, its fixes put into nav_errors_.
  bool simulateCanyonGnss(size_t epochs, std::string* error);
};

}  // namespace osm_graph_slam::sim
