#pragma once
// Localisation on a saved map (ART-SLAM LOC): a pose UKF predicted by the gyro (or a constant
// velocity and turn rate) and corrected by registering each prefiltered scan against the map
// cloud around the predicted pose; a registration whose fitness or correction is out of bounds
// does not correct. Global localisation from the map's keyframes (Scan Context retrieval, then
// scan-to-keyframe registration verified by fitness and overlap) starts the filter when no
// initial pose is given, and re-starts it when the filter diverged (bad matches for N scans).
// Scans farther than off_map_distance from every keyframe are flagged off the map: predicted
// only, never corrected against a map that is not there.
#include <Eigen/Geometry>
#include <algorithm>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/cloud/scan_deskew.h"
#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/landmarks/landmark_map.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/localization/pose_ukf.h"
#include "osm_graph_slam/loop/landmark_loop_source.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

struct LocalizationParams {
  RegistrationParams registration;  ///< scan-to-map (tracking)
  double map_voxel_size = 0.5;      ///< [m] the map cloud is reduced to this before use
  double scan_voxel_size = 1.0;     ///< [m] scans are reduced to this before matching (0: as given)
  double local_map_radius = 60.0;   ///< [m] map points within this of the prediction (2D)
  double local_map_update_distance = 8.0;  ///< [m] rebuild the local map after this motion
  double max_fitness = 0.5;                ///< [m^2] worse matches do not correct
  /// ... nor matches above this x the median fitness of the recent accepted ones (a scan that
  /// slides along a street it does not belong to fits, but worse than usual); 0: off
  double fitness_ratio = 2.5;
  double fitness_ratio_floor = 0.1;            ///< [m^2] the adaptive limit never goes below this
  double max_correction_trans = 1.5;           ///< [m] registration vs prediction
  double max_correction_angle = 0.15;          ///< [rad]
  double measurement_position_std = 0.05;      ///< [m] of an accepted registration
  double measurement_orientation_std = 0.005;  ///< [rad]
  /// Diverged (re-localise globally) when divergence_scans of the last divergence_window
  /// corrections were rejected. A window of divergence_scans or less: rejections in a row. A
  /// filter carried off to a wrong place has corrections there accepted and rejected in turn,
  /// which a count in a row misses for seconds (doc/localization.md "Divergence over a window").
  int divergence_scans = 5;
  int divergence_window = 10;
  /// The window actually used: never shorter than divergence_scans.
  int effectiveDivergenceWindow() const {
    return std::max({divergence_window, divergence_scans, 1});
  }
  /// GNSS as a consistency check (setGnssFix; never a correction): gnss_check_fixes fixes in a
  /// row farther than gnss_check_distance (or 5 of their reported deviations) from the tracked
  /// pose are a divergence, and a global answer that far from the latest fix is refused. A
  /// filter carried to a look-alike street fits there nearly as well as on its own (fitness
  /// 1.5x), which the fitness tests miss for seconds; a consumer receiver is never 10 m off for
  /// half a second in a row. 0: off. Only for a map package with an ENU origin.
  double gnss_check_distance = 10.0;  ///< [m] the fix's error plus the map's own GNSS offset
  int gnss_check_fixes = 5;
  double gnss_max_age = 1.0;       ///< [s] an older fix (scan time) is not used
  double off_map_distance = 20.0;  ///< [m] farther from every keyframe: off the map
  /// Off the map the pose is carried by scan-to-scan registration (LiDAR odometry), each step an
  /// update of this noise; false: by the motion model alone (a filter started off the map with
  /// an unknown velocity then never reaches the map).
  bool off_map_odometry = true;
  double off_map_step_position_std = 0.05;     ///< [m] per scan-to-scan step
  double off_map_step_orientation_std = 0.01;  ///< [rad]
  int min_points = 100;                        ///< fewer scan points: no correction
  /// Motion compensation of each tracked scan by the filter's predicted motion (scan_deskew.h;
  /// as the SLAM tracker does, so that scans and map agree). sensor_to_base: the LiDAR mounting.
  bool deskew = true;
  SweepTiming sweep;
  Eigen::Isometry3d sensor_to_base = Eigen::Isometry3d::Identity();
  PoseUkfParams ukf;
  double init_position_std = 0.5;      ///< [m] a given or global initial pose
  double init_orientation_std = 0.05;  ///< [rad]
  double init_velocity_std = 5.0;      ///< [m/s] unknown at the start
  double init_rate_std = 0.5;          ///< [rad/s]
  // Global localisation.
  /// Where the candidate places come from: scan_context | geometric_hierarchy (the trunks and
  /// poles of the scan against those of every map keyframe, GeoSLAM; doc/landmarks.md) |
  /// combined (the hierarchy's place first, then Scan Context's). All get the same registration.
  std::string global_method = "scan_context";
  LandmarkExtractionParams landmark_extraction = loopLandmarkExtractionDefaults();
  LandmarkPlaceRecognitionParams landmarks;
  /// What the scan's landmarks are matched with: keyframes (each map keyframe's own) | global
  /// (the landmarks that landmark_map_params.min_observations keyframes agree on, merged into one
  /// map and indexed in tiles along the mapped path; GeoSLAM §4.3, doc/landmarks.md).
  std::string landmark_map = "keyframes";
  LandmarkMapParams landmark_map_params;
  int global_ring_key_candidates = 30;          ///< nearest ring keys searched
  int global_candidates = 8;                    ///< best Scan Context matches registered
  double global_max_descriptor_distance = 0.6;  ///< upper bound of the limit below
  /// A candidate's Scan Context distance must be below this quantile of the distances between
  /// different places of the same map (keyframes global_impostor_distance apart): the rate at
  /// which another place would pass as this one. Sensor- and map-specific, learnt at load.
  double global_false_match_rate = 0.01;
  double global_impostor_distance = 40.0;  ///< [m] keyframes this far apart are other places
  int global_impostor_pairs = 2000;        ///< sampled keyframe pairs (deterministic)
  double global_max_fitness = 0.25;        ///< [m^2] after the fine registration
  /// Of the scan points inside the registered map region: fraction within overlap_distance of
  /// the map (points beyond the region cannot be explained and do not count)
  double global_min_overlap = 0.6;
  double global_overlap_distance = 0.6;  ///< [m]
  /// The overlap limit is learnt at load from this many map keyframes (evenly spread): each is
  /// registered at its own place (its own points left out of the map) and at up to
  /// global_overlap_impostor_places other places (>= global_impostor_distance away) that Scan
  /// Context proposes for it. The limit is the overlap that impostors passing the fitness test
  /// exceed at global_false_match_rate (at least global_min_overlap), if that lies below what the
  /// own places reach at that rate; otherwise the overlap cannot separate places in this map
  /// and global_min_overlap stays (the ambiguity test and the confirmation carry). 0:
  /// global_min_overlap alone.
  int global_overlap_samples = 30;
  int global_overlap_impostor_places = 2;
  /// [m] each map keyframe's cloud is also described (Scan Context) as seen from this far to its
  /// left and right, so that a scan taken off the map drive's path (another lane, a corner cut
  /// differently) still finds the keyframe. Searched only when no keyframe's place passes
  /// (global_ring_key_candidates keyframes' worth of views). 0: off.
  double global_side_view_offset = 6.0;
  /// OSM walls (enableOsmWalls; OSM-SLAM §5.1): when neither the keyframes nor their side views
  /// give a place, the scan's wall segments are matched (line matcher, heading unbounded) with
  /// the map package's buildings around the GNSS fix, or without a fix around points of the map
  /// drive's path global_osm_spacing apart; the best matches become places for the same
  /// registration, tests and ambiguity check. Places are where the walls are, not where the map
  /// drive's keyframes looked from.
  bool global_osm_walls = true;
  double global_osm_search_radius = 10.0;  ///< [m] translation searched around each centre
  double global_osm_spacing = 15.0;        ///< [m] between centres along the path (no fix)
  double global_osm_wall_radius = 45.0;    ///< [m] walls seen within this of a centre are matched
  int global_osm_min_segments = 3;         ///< fewer wall segments in the scan: no search
  double global_osm_min_fitness = -100.0;  ///< line matcher fitness of a place at least
  int global_osm_min_matched = 2;          ///< matched wall segments of a place at least
  /// [s] of scan time between walls searches that keep finding nothing (lost off the map, each
  /// costs 0.5-1 s): after the 1st, 2nd, 3rd failure in a row 1/8, 1/4, 1/2 of it, then all of
  /// it; direct globalLocalize calls always search.
  double global_osm_interval = 1.0;
  /// A walls place passes only if this fraction of its structure points (above the ground) lies
  /// within global_overlap_distance of the map as well (Karlsruhe pair: right walls places
  /// 0.73-0.92, Scan Context's right places >= 0.66; a street turned by 90 deg: 0.28).
  double global_osm_min_structure_overlap = 0.5;
  /// [m] above the ground (the map's Scan Context sensor_height below base_link): structure
  /// points, whose overlap is reported (diagnosis; the ground fits any flat place)
  double global_structure_height = 0.5;
  double global_coarse_max_correspondence = 4.0;  ///< [m] first, coarse registration
  double global_voxel_size = 1.0;                 ///< [m] coarse source/target voxel
  /// Another candidate more than 2 m away whose structure cost (GlobalCandidate) is within this
  /// factor of the best's makes the answer ambiguous: refused.
  double global_ambiguity_ratio = 1.5;
  /// A global answer is confirmed by a second, independent one this many scans later (tracked in
  /// between) that agrees within 1 m and 2 deg; until then the scans are not reported localised.
  /// 0: the first answer is taken.
  int global_confirm_after = 3;
};

/// A GNSS fix in the map frame: position and its horizontal deviation (0: unknown).
struct GnssFix {
  double stamp = 0.0;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double std = 0.0;  ///< [m]
};

enum class LocalizationStatus {
  kUninitialized,  ///< no pose yet (global localisation failed on this scan)
  kTracking,       ///< corrected by the map
  kPredicted,      ///< on the map but the registration was rejected: prediction only
  kOffMap,         ///< too far from the map: prediction only, flagged
  kRelocalized,    ///< the filter was (re-)started by global localisation on this scan
};

const char* toString(LocalizationStatus status);

struct LocalizationOutput {
  LocalizationStatus status = LocalizationStatus::kUninitialized;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< base_link in map
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double fitness = -1.0;          ///< of this scan's registration (-1: none)
  double distance_to_map = 0.0;   ///< [m] to the nearest keyframe (2D)
  bool diverged = false;          ///< the filter was declared diverged on this scan
  bool diverged_by_gnss = false;  ///< ... because GNSS fixes contradicted it (gnss_check_distance)
  /// The filter's predicted motion since the previous scan's estimate (base_link frame): a
  /// continuous dead reckoning without the map's corrections (the nodelet's odom frame).
  /// Identity when nothing was predicted (not started, or started on this scan).
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
};

/// One place global localisation considered (for diagnosis and tests).
struct GlobalCandidate {
  uint64_t keyframe_id = 0;
  std::string source = "scan_context";  ///< or geometric_hierarchy, side_view, osm_walls
  double descriptor_distance = 1.0;     ///< Scan Context (-1: a hierarchy or walls candidate)
  double wall_fitness = 0.0;            ///< the line matcher's (osm_walls candidates)
  /// coarse_failed | fine_failed | fitness | overlap | structure (osm_walls) | passed
  std::string outcome;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< after registration
  double fitness = -1.0, overlap = 0.0;
  double structure_overlap = 0.0;  ///< the overlap of the points above the ground only
  /// Mean truncated squared distance [m^2] of the points above the ground to the map (each
  /// min(d^2, global_overlap_distance^2)): how well the place explains what tells places apart;
  /// the global search ranks places by it and refuses one with a rival close in it.
  double structure_cost = -1.0;
};

struct GlobalLocalizationResult {
  bool success = false;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  uint64_t keyframe_id = 0;
  std::string source;  ///< of the answer: scan_context | geometric_hierarchy
  double descriptor_distance = 1.0;
  double fitness = -1.0;
  double overlap = 0.0;
  int candidates_tried = 0;
  std::string message;
  std::vector<GlobalCandidate> candidates;  ///< every place registered, in the order tried
};

struct LocalizationStats {
  size_t scans = 0, tracking = 0, predicted = 0, off_map = 0, uninitialized = 0;
  size_t off_map_odometry = 0;  ///< off-map scans carried by scan-to-scan registration
  size_t relocalizations = 0, global_attempts = 0, global_failures = 0, divergences = 0;
  size_t global_ambiguous = 0;      ///< of the failures: refused as ambiguous
  size_t global_disagreements = 0;  ///< a confirming answer disagreed: searched again
  size_t gnss_divergences = 0;      ///< divergences declared by the GNSS check
  size_t global_gnss_refusals = 0;  ///< global answers refused: too far from the GNSS fix
  double registration_ms = 0.0, local_map_ms = 0.0, global_ms = 0.0, filter_ms = 0.0;
  size_t local_map_builds = 0;
  double global_descriptor_limit = 0.0;  ///< the learnt Scan Context limit (see params)
  size_t global_impostor_pairs = 0;      ///< the pairs it was learnt from
  size_t global_by_hierarchy = 0;        ///< global answers whose place the hierarchy proposed
  size_t global_by_side_view = 0;        ///< global answers from a keyframe's side view
  size_t global_by_osm_walls = 0;        ///< global answers whose place the OSM walls proposed
  size_t global_osm_searches = 0;        ///< searches that matched the walls (the fallback ran)
  double global_osm_ms = 0.0;            ///< of which wall extraction and matching
  double global_overlap_limit = 0.0;     ///< the learnt overlap limit (see params)
  size_t global_overlap_own = 0;         ///< own places it was learnt from
  size_t global_overlap_impostors = 0;   ///< impostor places that passed the fitness test
  double global_overlap_own_low = 0.0;   ///< the own places' overlap at global_false_match_rate
  double global_overlap_impostor_high = 0.0;  ///< the impostors' at 1 - global_false_match_rate
  double global_overlap_learn_ms = 0.0;
};

/// The overlap limit from the overlaps of map keyframes at their own places and at impostor
/// places (see LocalizationParams::global_overlap_samples).
struct OverlapLimit {
  double limit = 0.0;
  double own_low = 0.0;        ///< the own places' overlap at the rate
  double impostor_high = 0.0;  ///< the impostors' at 1 - rate
  bool separable = false;      ///< impostor_high < own_low, from >= 10 own places
};
OverlapLimit learnOverlapLimitFrom(std::vector<double> own, std::vector<double> impostor,
                                   double min_overlap, double rate);

/// How a scan registered at a place agrees with the map there.
struct PlaceFit {
  double overlap = 0.0;            ///< fraction of the points within inlier_distance of the map
  double structure_overlap = 0.0;  ///< the same of the points above structure_z (not the ground)
  double structure_cost = 0.0;     ///< GlobalCandidate::structure_cost
};
/// Of the points of cloud (base_link) at pose that lie inside the map region (centre, radius - 1
/// m: only they can have a map point near them); structure: cloud z > structure_z.
PlaceFit measurePlaceFit(const PointCloud& cloud, const Eigen::Isometry3d& pose,
                         const PointCloudConstPtr& map_region, const Eigen::Vector2d& centre,
                         double radius, double inlier_distance, double structure_z);

class Localizer {
 public:
  Localizer(const LocalizationParams& params, std::shared_ptr<const MapPackage> map);
  ~Localizer();

  /// Forgets the pose: the next scan is localised globally (time jumped back, bag replayed).
  void reset();

  /// Starts the filter at a known pose (rviz /initialpose, --initial-pose).
  void setInitialPose(const Eigen::Isometry3d& pose, double stamp);

  /// A GNSS fix in the map frame (x, y) with its horizontal deviation (0: unknown): checks the
  /// tracked pose and global answers on the scans up to gnss_max_age later (gnss_check_distance).
  void setGnssFix(double stamp, const Eigen::Vector2d& xy, double std = 0.0);

  /// One prefiltered scan in base_link at stamp; gyro = body rates and accel = specific force
  /// (gravity included) in base_link since the last scan, if the drive has an IMU.
  LocalizationOutput process(double stamp, const PointCloudConstPtr& cloud,
                             const std::optional<Eigen::Vector3d>& gyro = std::nullopt,
                             const std::optional<Eigen::Vector3d>& accel = std::nullopt);

  /// Lets global localisation search the map package's buildings with the scan's walls
  /// (global_osm_walls): extraction and matcher parameters are the SLAM pipeline's. Returns the
  /// number of buildings (0: the package has none, nothing changes).
  size_t enableOsmWalls(const WallPointExtractorParams& walls,
                        const LineSegmentExtractorParams& segments,
                        const LineMatcherParams& matcher);

  /// Where is this scan on the map, with no prior (exposed for tests and the global tool).
  GlobalLocalizationResult globalLocalize(const PointCloudConstPtr& cloud);

  bool initialized() const { return ukf_.initialized(); }
  const LocalizationParams& params() const { return params_; }
  /// The LiDAR's mounting for deskewing, once known (the nodelet reads it from TF).
  void setSensorToBase(const Eigen::Isometry3d& sensor_to_base) {
    params_.sensor_to_base = sensor_to_base;
  }
  const LocalizationStats& stats() const { return stats_; }
  /// The last global localisation attempt (diagnosis).
  const GlobalLocalizationResult& lastGlobal() const { return last_global_; }
  const PoseUkf& filter() const { return ukf_; }
  /// [m] 2D distance from position to the nearest map keyframe.
  double distanceToMap(const Eigen::Vector3d& position) const;

 private:
  struct Impl;
  struct Place;
  /// walls_due = false: no OSM walls search this time (global_osm_interval).
  GlobalLocalizationResult searchGlobally(const PointCloudConstPtr& cloud, bool walls_due);
  /// globalLocalize for the scan at stamp, failed walls searches backing off (global_osm_interval).
  GlobalLocalizationResult globalLocalizeAt(const PointCloudConstPtr& cloud, double stamp);
  /// The places worth registering, best first, 5 m apart (global_method decides the sources).
  std::vector<Place> candidatePlaces(const PointCloudConstPtr& cloud);
  void addScanContextPlaces(const PointCloudConstPtr& cloud, std::vector<Place>& places) const;
  /// The keyframes whose Scan Context is under the limit, nearest first (only those at least
  /// away_distance from away_from, when given); with side_views their side views instead. The
  /// overlap limit is learnt from the keyframes' own proposals only: side views propose more
  /// impostors, and a limit from the few that pass fitness rose above a correct place's overlap
  /// of a drive with another sensor (localization.test).
  std::vector<Place> scanContextPlaces(const ScanContext& query, const Eigen::Vector2d* away_from,
                                       double away_distance, bool side_views) const;
  /// Places from the scan's walls matched with the buildings (global_osm_walls), best first.
  std::vector<Place> osmWallPlaces(const PointCloudConstPtr& cloud);
  /// The place of a walls match (planar pose in the map, the line matcher's fitness).
  /// The place of a planar map pose; the nearest keyframe gives the height and the slope.
  Place placeAt(const Pose2& pose, const char* source) const;
  /// geometric_hierarchy / combined: the map keyframes' landmarks, indexed per keyframe or
  /// merged into the map's landmarks (landmark_map).
  void buildLandmarkIndex();
  /// Where the wall search looks: points along the map drive's path, only those near the GNSS
  /// fix (and the fix) when there is a recent one.
  std::vector<Eigen::Vector2d> osmSearchCentres(const Eigen::Vector2d* fix, double fix_limit) const;
  /// The first places of the list 5 m apart from each other, at most max_places.
  std::vector<Place> distinctPlaces(const std::vector<Place>& places, int max_places) const;
  /// Side views of every keyframe (global_side_view_offset): its cloud described from beside it.
  void addSideViews();
  void learnDescriptorLimit();
  void learnOverlapLimit();
  /// The overlap of map keyframe index at its own place without its own points (-1: no map
  /// around it).
  double ownPlaceOverlap(size_t index) const;
  /// [m] the map region a global candidate is registered against.
  double globalSearchRadius() const { return std::min(params_.local_map_radius, 50.0); }
  /// Registers the cloud at each place and keeps the best by structure cost in result (appends
  /// to its candidates). True: refused as ambiguous (result.success false).
  bool verifyPlaces(const PointCloudConstPtr& cloud, const std::vector<Place>& places,
                    GlobalLocalizationResult& result);
  /// A walls place (result.candidates[best]) with a rival among the fitting walls places: the
  /// answer is refused (result.success false). True: ambiguous.
  bool wallsAmbiguous(GlobalLocalizationResult& result, size_t best,
                      const std::vector<size_t>& fitting) const;
  /// Coarse, then fine registration of the cloud at the place; fills the record's pose, fitness,
  /// overlap and outcome (up to "overlap": the limit is the caller's). True: it passed the
  /// fitness test.
  bool registerAtPlace(const PointCloudConstPtr& cloud, const PointCloudConstPtr& coarse_source,
                       const Place& place, GlobalCandidate& record) const;
  PlaceFit overlapAt(const PointCloud& cloud, const Eigen::Isometry3d& pose,
                     const PointCloudConstPtr& target, const Eigen::Vector2d& centre,
                     double radius) const;
  /// Off the map: the filter's step from before (predicted_motion over dt) corrected by
  /// registering the scan against the previous one. True: an update was made.
  bool carryByScanOdometry(const PointCloudConstPtr& cloud, const Eigen::Isometry3d& before,
                           const Eigen::Isometry3d& predicted_motion, double dt);
  /// The scan deskewed by motion over dt (when deskew is on).
  PointCloudConstPtr deskewedScan(const PointCloudConstPtr& cloud, const Eigen::Isometry3d& motion,
                                  double dt) const;
  /// The latest GNSS fix, if recent at stamp and the check is on (null otherwise).
  const Eigen::Vector2d* recentGnssFix(double stamp, double* limit) const;
  /// Counts a recent fix that contradicts the tracked pose (each fix once). True: diverged.
  bool gnssContradictsTracking(const Eigen::Isometry3d& pose, double stamp);
  /// ... reduced to scan_voxel_size for matching.
  PointCloudConstPtr reducedScan(const PointCloudConstPtr& scan) const;
  double descriptor_limit_ = 0.6;  ///< learnt at construction
  double overlap_limit_ = 0.6;     ///< learnt at construction
  LocalizationParams params_;
  std::shared_ptr<const MapPackage> map_;
  std::unique_ptr<Impl> impl_;
  PoseUkf ukf_;
  LocalizationStats stats_;
  GlobalLocalizationResult last_global_;
  double last_stamp_ = 0.0;
  std::deque<bool> recent_rejections_;  ///< of the last divergence_window corrections
  bool searching_ = true;               ///< waiting for a global localisation
  bool confirming_ = false;             ///< started from a global answer not yet confirmed
  int confirm_wait_ = 0;
  std::vector<double> recent_fitness_;  ///< of the last accepted matches (ring of 20)
  size_t recent_next_ = 0;
};

}  // namespace osm_graph_slam
