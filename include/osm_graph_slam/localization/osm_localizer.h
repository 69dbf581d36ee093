#pragma once
// Localisation from OpenStreetMap alone (OSM-SLAM §5.1 re-localisation, issue 21 item 4): no
// prior drive, no point-cloud map. A planar EKF is predicted by the LiDAR odometry, corrected by
// GNSS fixes and by aligning the scan's wall segments with the OSM building outlines around the
// prediction (the line matcher's global matching). The state carries the OSM map's offset from
// the GNSS frame (the datum): real extracts are often shifted as a whole by metres, so the walls
// say where the vehicle is relative to the map and GNSS says where the map is.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

struct OsmLocalizerParams {
  bool use_osm = true;   ///< false: odometry + GNSS only (the baseline the OSM updates must beat)
  bool use_gnss = true;  ///< false: odometry + OSM only (after a GNSS-less start: initial pose)
  // Prediction noise of the odometry increment between scans.
  double odometry_std_per_m = 0.02;        ///< [m/m] translation std per metre driven
  double odometry_yaw_std_per_m = 5e-4;    ///< [rad/m]
  double odometry_yaw_std_per_rad = 0.01;  ///< [rad/rad] of the turn
  // GNSS.
  double gnss_std = 2.0;         ///< [m] white noise of a fix when the receiver reports none
  double gnss_gate_chi2 = 13.8;  ///< 2 DOF, 99.9 %: a fix further off is rejected (multipath)
  /// The receiver's slowly varying bias (first-order Gauss-Markov), estimated so that hundreds of
  /// fixes do not average into false certainty: only the white part averages out.
  double gnss_bias_std = 1.0;   ///< [m] stationary deviation per axis
  double gnss_bias_tau = 90.0;  ///< [s] correlation time (0: no bias state)
  // The OSM map's offset from the GNSS frame (translation only).
  double datum_std = 1.5;               ///< [m] initial uncertainty of the offset
  double datum_walk_std_per_m = 0.005;  ///< [m/m] the offset may change slowly along the drive
  // OSM wall matching.
  double match_every_distance = 2.0;  ///< [m] driven between two matching attempts
  double query_radius = 45.0;         ///< [m] buildings within this of the prediction are matched
  int min_segments = 3;               ///< fewer wall segments in the scan: no attempt
  double min_fitness = -100.0;        ///< line matcher fitness below this: no update
  int min_matched = 2;                ///< matched wall segments below this: no update
  /// Deviation of the best possible match (weaker matches scale down, as the back-end's global
  /// priors); besides the matcher's own error it stands for each building's own OSM error, which
  /// the datum (common to all) cannot absorb.
  double osm_std_xy = 0.7;       ///< [m]
  double osm_std_yaw = 0.02;     ///< [rad]
  double osm_gate_chi2 = 11.34;  ///< 3 DOF, 99 %: a match this far from the prediction is refused
  // Start.
  double init_yaw_std = 0.05;  ///< [rad] heading from the IMU (or from global matching)
};

enum class OsmLocalizationStatus {
  kUninitialized,  ///< no start yet (no fix, or no heading)
  kDeadReckoning,  ///< predicted only on this scan
  kGnss,           ///< corrected by a GNSS fix on this scan
  kOsm,            ///< corrected by the OSM walls on this scan (and maybe GNSS)
};
const char* toString(OsmLocalizationStatus status);

struct OsmLocalizationOutput {
  OsmLocalizationStatus status = OsmLocalizationStatus::kUninitialized;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< base_link in the GNSS ENU frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();    ///< of x, y, yaw
  Eigen::Vector2d datum = Eigen::Vector2d::Zero();         ///< the OSM map's estimated offset
  bool osm_attempted = false;                              ///< wall matching ran on this scan
  double osm_fitness = 0.0;  ///< of that match (when attempted and successful)
  std::string osm_outcome;   ///< accepted | few_segments | no_buildings | failed | weak | gated
  std::string osm_message;   ///< the line matcher's reason when it failed
};

struct OsmLocalizationStats {
  size_t scans = 0, uninitialized = 0;
  size_t gnss_used = 0, gnss_rejected = 0;
  size_t osm_attempts = 0, osm_accepted = 0, osm_few_segments = 0, osm_no_buildings = 0;
  size_t osm_failed = 0, osm_weak = 0, osm_gated = 0;
  double walls_ms = 0.0, matching_ms = 0.0, filter_ms = 0.0;
};

class OsmLocalizer {
 public:
  static constexpr int kStateSize = 7;
  /// buildings: outlines and wall segments in the same ENU frame as the GNSS fixes.
  OsmLocalizer(const OsmLocalizerParams& params, std::vector<Building> buildings,
               const WallPointExtractorParams& walls = {},
               const LineSegmentExtractorParams& segments = {},
               const LineMatcherParams& matcher = {});
  ~OsmLocalizer();

  /// More buildings (the osm_buffer nodelet's answers as the vehicle moves); ids already held are
  /// skipped. Returns how many were added.
  size_t addBuildings(std::vector<Building> buildings);
  size_t numBuildings() const;

  /// Starts at a known planar pose (x, y, yaw in the GNSS frame) with these deviations.
  void initialize(const Eigen::Vector3d& pose, double position_std, double yaw_std);

  /// One scan: odom_pose = the LiDAR odometry's base_link pose (any fixed odom frame); cloud =
  /// the prefiltered scan in base_link; gnss = the fix (x, y) and its deviation, if any; yaw = the
  /// IMU heading in the GNSS frame, if any (used only to start).
  OsmLocalizationOutput process(double stamp, const Eigen::Isometry3d& odom_pose,
                                const PointCloudConstPtr& cloud,
                                const std::optional<Eigen::Vector2d>& gnss,
                                std::optional<double> gnss_std, const std::optional<double>& yaw);

  bool initialized() const { return initialized_; }
  const OsmLocalizationStats& stats() const { return stats_; }
  const OsmLocalizerParams& params() const { return params_; }

 private:
  struct Impl;
  void predict(const Eigen::Isometry3d& odom_pose, double dt);
  bool correctGnss(const Eigen::Vector2d& fix, double std);
  void correctOsm(const PointCloudConstPtr& cloud, OsmLocalizationOutput& out);
  bool tryStartWithoutHeading(const PointCloudConstPtr& cloud, const Eigen::Vector2d& fix,
                              double std);
  OsmLocalizationOutput output(const Eigen::Isometry3d& odom_pose) const;

  OsmLocalizerParams params_;
  std::unique_ptr<Impl> impl_;
  bool initialized_ = false;
  /// x y yaw (GNSS frame), dx dy (the OSM map's offset), bx by (the GNSS receiver's bias)
  Eigen::Matrix<double, kStateSize, 1> state_ = Eigen::Matrix<double, kStateSize, 1>::Zero();
  Eigen::Matrix<double, kStateSize, kStateSize> cov_ =
      Eigen::Matrix<double, kStateSize, kStateSize>::Zero();
  double last_stamp_ = 0.0;
  std::optional<Eigen::Isometry3d> last_odom_;
  double since_match_ = 1e9;  ///< [m] driven since the last matching attempt
  OsmLocalizationStats stats_;
};

}  // namespace osm_graph_slam
