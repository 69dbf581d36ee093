#pragma once
// Three-phase loop detection (ART-SLAM thesis section 3.1.7):
//  1. odometry candidates: earlier keyframes far enough along the trajectory and near enough in
//     space (radius growing with the travelled distance between them to absorb drift);
//  2. ranking: ring-key distance, then Scan Context distance with column-shift alignment; the
//     best k survive;
//  3. verification: a coarse stage, then 3D registration (fine stage); a candidate is accepted
//     when fitness, overlap and (when available) odometry consistency all pass. With odometry the
//     coarse stage is a correlative bird's-eye-view search over every pose the odometry check
//     could accept, which also rejects ambiguous matches (a second placement fits almost as
//     well); without odometry it is a coarse GICP seeded with the Scan Context yaw.
// Without odometry (re-localisation) phase 1 is replaced by the ring-key KD-tree over all
// keyframes.
// Candidate source (`method`): scan_context (phase 2 above), geometric_hierarchy (the landmark
// layout proposes one keyframe and a planar transform, LandmarkLoopSource) or combined (Scan
// Context's candidates first, then the hierarchy's). Every candidate gets the same verification.
#include <Eigen/Geometry>
#include <cstdint>
#include <list>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/cloud_store.h"
#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/logger.h"
#include "osm_graph_slam/landmarks/landmark_extraction.h"
#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"
#include "osm_graph_slam/loop/bev_correlation.h"
#include "osm_graph_slam/loop/landmark_loop_source.h"
#include "osm_graph_slam/loop/scan_context.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct LoopDetectorParams {
  /// Candidate source: scan_context | geometric_hierarchy | combined.
  std::string method = "scan_context";
  ScanContextParams scan_context;
  /// geometric_hierarchy / combined: trunk and pole extraction and the place recognizer.
  LandmarkExtractionParams landmark_extraction = loopLandmarkExtractionDefaults();
  LandmarkPlaceRecognitionParams landmarks;

  // Phase 1: odometry candidates.
  /// The pose the callers give the detector for each keyframe (and so search around): odometry
  /// (the tracker's) or map (the back-end's latest estimate, map->odom * odometry; bounded by
  /// GNSS, INS heading and OSM priors where the odometry drifts). The detector itself does not
  /// read it.
  std::string search_frame = "map";
  double min_accum_distance_gap = 25.0;   ///< [m] along the trajectory
  double search_radius_base = 10.0;       ///< [m] around the odometry position
  double search_radius_per_meter = 0.05;  ///< [m/m] growth with the travelled distance gap
  double search_radius_max = 35.0;        ///< [m]

  // Phase 2: ranking.
  int ring_key_candidates = 20;          ///< kept after the ring-key distance
  int num_candidates = 3;                ///< k: verified by registration
  double max_descriptor_distance = 0.6;  ///< Scan Context distance [0, 1]
  /// Also verify the candidate nearest to the odometry position (repetitive facades make the
  /// descriptor ranking ambiguous between aliases one facade period apart).
  bool verify_odometry_nearest = true;

  // Phase 3: verification.
  double voxel_size = 0.6;  ///< [m] downsampling of the stored clouds (0 = none)
  /// [m] the query's cloud in the fine stage (source; <= voxel_size: the stored resolution).
  /// The target keeps voxel_size, and the overlap is measured at voxel_size.
  double fine_query_voxel_size = 0.0;
  /// Query points aligned in the fine stage at most (0: all), evenly spread; the covariances
  /// still use all of the query's points as neighbours, the target and the overlap are unchanged
  /// (fast_gicp / fast_vgicp; RegistrationParams::max_source_points). 2000 of the ~4,200 points
  /// at 0.6 m: fine stage 0.57x, the same loops, errors +0.1 mm mean (doc/loop.md "The fine
  /// stage on a subset of the query's points").
  int fine_max_source_points = 2000;
  /// Voxel filter of the clouds: "own" (voxelCentroids: pcl::VoxelGrid's voxels and centroids,
  /// ~2.5x faster) | "pcl" (pcl::VoxelGrid, the baseline).
  std::string voxel_filter = "own";
  int min_points = 200;  ///< keyframes with fewer points are stored without cloud
  /// Coarse stage with odometry: "correlative" (BEV search over the odometry tolerance window +
  /// ambiguity test) | "gicp" (coarse GICP from the odometry and zero-translation seeds).
  /// Without odometry (relocalize) the coarse GICP stage is used in both cases.
  std::string coarse_method = "correlative";
  BevCorrelationParams correlative;  ///< heights/ground taken from scan_context at construction
  /// Reject a match whose runner-up placement scores at least this fraction of the best one.
  double max_ambiguity = 0.9;
  /// [m] the fine stage must stay within this of the correlative peak (else it left the basin
  /// that the whole-window search chose, and the BEV and 3D evidence disagree).
  double max_refinement_shift = 2.0;
  int field_cache_size = 64;  ///< likelihood fields of recent candidates kept (LRU; 0: none)
  /// Candidate clouds prepared for the fine stage (KD-tree, covariances) kept (LRU; ~0.5 MB
  /// each): a revisit verifies the same keyframes for consecutive queries.
  int candidate_cache_size = 16;
  /// Where the stored keyframes' downsampled clouds are kept: encoded, spilled to disk beyond
  /// resident_mb (~25 kB a keyframe encoded; 64 MB: the last ~2,500 in memory).
  CloudStoreParams cloud_store = [] {
    CloudStoreParams p;
    p.resident_mb = 64.0;
    return p;
  }();
  double coarse_voxel_size = 1.5;                   ///< [m] coarse GICP stage cloud resolution
  double coarse_max_correspondence_distance = 4.0;  ///< [m] coarse GICP stage (0 = none)
  /// [m^2] early reject: a coarse result with a larger fitness skips the fine stage (<= 0: off).
  double coarse_max_fitness = 0.0;
  RegistrationParams registration;  ///< back-end (method) and fine stage settings
  double max_fitness = 0.2;         ///< [m^2] mean squared inlier distance
  double overlap_distance = 0.5;    ///< [m] a source point is an inlier within this distance
  double min_overlap = 0.5;         ///< inlier fraction of the query cloud
  bool seed_translation_from_odometry = true;  ///< else the seed translation is zero
  bool retry_zero_translation_seed = true;     ///< second try with zero translation
  /// Stop verifying at the first accepted candidate (candidates are verified best first).
  bool stop_at_first_accepted = true;
  bool check_odometry_consistency = true;
  double odometry_translation_tolerance_base = 2.0;        ///< [m]
  double odometry_translation_tolerance_per_meter = 0.01;  ///< [m/m] of distance gap
  double odometry_yaw_tolerance_base = 0.05;               ///< [rad]
  double odometry_yaw_tolerance_per_meter = 0.0002;        ///< [rad/m] of distance gap

  // Information matrix: stddev = scale * RMS residual (sqrt(fitness)), clamped.
  double translation_stddev_per_rms = 1.0;  ///< [m/m]
  double rotation_stddev_per_rms = 0.05;    ///< [rad/m]
  double min_translation_stddev = 0.02;     ///< [m]
  double max_translation_stddev = 1.0;      ///< [m]
  double min_rotation_stddev = 0.002;       ///< [rad]
  double max_rotation_stddev = 0.1;         ///< [rad]
};

struct LoopKeyframe {
  uint64_t id = 0;
  Eigen::Isometry3d odom_pose = Eigen::Isometry3d::Identity();  ///< base_link in odom
  double accum_distance = 0.0;  ///< [m] travelled since the first keyframe
  PointCloudConstPtr cloud;     ///< in base_link (the sensor frame of the descriptor)
};

struct DetectedLoop {
  uint64_t from_id = 0;                                             ///< query (current) keyframe
  uint64_t to_id = 0;                                               ///< earlier keyframe
  Eigen::Isometry3d relative_pose = Eigen::Isometry3d::Identity();  ///< from in to's frame
  Matrix6d information = Matrix6d::Identity();                      ///< x y z roll pitch yaw
  double descriptor_distance = 1.0;
  double descriptor_yaw = 0.0;          ///< [rad] Scan Context estimate used as seed
  double fitness = 0.0;                 ///< [m^2]
  double overlap = 0.0;                 ///< inlier fraction
  std::string source = "scan_context";  ///< candidate source: scan_context | geometric_hierarchy
  int landmark_inliers = 0;             ///< geometric_hierarchy: landmark inliers of the proposal
};

/// Verification of one candidate.
struct CandidateOutcome {
  uint64_t id = 0;
  std::string source = "scan_context";  ///< scan_context | geometric_hierarchy
  double descriptor_distance = 1.0;
  double coarse_fitness = -1.0;  ///< [m^2] (-1: no coarse stage)
  double fitness = -1.0;         ///< [m^2] fine stage (-1: rejected before it)
  double overlap = 0.0;
  double bev_score = -1.0;  ///< correlative best score (-1: no correlative stage)
  double ambiguity = -1.0;  ///< runner-up / best correlative score
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  ///< of the last stage run
  /// accepted | coarse_fitness | coarse_odometry | landmark_odometry | correlative | ambiguous |
  /// fitness | overlap | odometry | refinement
  std::string verdict;
};

/// What happened to one query, for diagnostics and benchmarks.
struct LoopQueryStats {
  std::vector<CandidateOutcome> outcomes;
  double descriptor_ms = 0.0;
  double candidates_ms = 0.0;
  double ranking_ms = 0.0;
  double verification_ms = 0.0;
  double prepare_ms = 0.0;      ///< query downsampling and BEV points, part of verification_ms
  double correlative_ms = 0.0;  ///< part of verification_ms (field + search)
  double coarse_ms = 0.0;       ///< part of verification_ms
  double fine_ms = 0.0;         ///< part of verification_ms
  /// Part of fine_ms: setTarget (fast_gicp: the KD-tree, or nothing for a cached candidate;
  /// covariances are computed during the alignment, for the points it matches).
  double fine_target_ms = 0.0;
  int fine_iterations = 0;              ///< summed over the fine registrations
  double overlap_ms = 0.0;              ///< part of verification_ms
  double landmark_extraction_ms = 0.0;  ///< geometric_hierarchy: trunks/poles of the query cloud
  double landmark_query_ms = 0.0;       ///< geometric_hierarchy: hierarchy + retrieval + matching
  int landmarks = 0;                    ///< extracted from the query cloud
  bool landmark_proposal = false;       ///< the hierarchy proposed a keyframe
  int phase1_candidates = 0;
  int phase2_candidates = 0;
  int verified = 0;            ///< candidate/seed pairs verified
  int fine_registrations = 0;  ///< of which reached the fine stage
  int rejected_coarse = 0;     ///< early rejects: coarse stage (fitness, odometry), landmark guess
  int rejected_fitness = 0;
  int rejected_overlap = 0;
  int rejected_odometry = 0;
  int rejected_ambiguous = 0;   ///< correlative runner-up too close to the best
  int rejected_refinement = 0;  ///< fine stage left the correlative peak
  bool accepted = false;
  std::string reason;  ///< why nothing was accepted
};

/// A database entry (public for tests and tools).
struct LoopDatabaseEntry {
  uint64_t id = 0;
  /// The pose searched around (odometry, or the map estimate with search_frame map).
  Eigen::Isometry3d odom_pose = Eigen::Isometry3d::Identity();
  double accum_distance = 0.0;
  ScanContext descriptor;
  StoredCloud cloud;         ///< voxel-downsampled, for the fine stage
  StoredCloud coarse_cloud;  ///< coarse stage
};

struct RankedCandidate {
  size_t index = 0;        ///< database index
  ScanContextMatch match;  ///< distance 1 when the query has no descriptor (geometric_hierarchy)
  /// geometric_hierarchy: the landmark transform (query in the candidate's frame), the seed.
  std::optional<Eigen::Isometry3d> landmark_guess;
  int landmark_inliers = 0;
};

class LoopDetector {
 public:
  /// Creates the registration back-ends with createRegistration(params.registration); throws
  /// std::invalid_argument for an unknown registration method.
  explicit LoopDetector(const LoopDetectorParams& params, LogSink log_sink = {});
  ~LoopDetector();

  /// Searches a loop for keyframe among the stored ones (odometry mode), then stores it.
  std::optional<DetectedLoop> process(const LoopKeyframe& keyframe);
  /// Odometry-mode search only (the keyframe is not stored).
  std::optional<DetectedLoop> detect(const LoopKeyframe& keyframe);
  /// Place recognition without odometry (re-localisation): ring-key tree over every stored
  /// keyframe at least min_accum_distance_gap before keyframe.accum_distance (a negative
  /// accum_distance searches all); odom_pose is ignored and no odometry check is made.
  std::optional<DetectedLoop> relocalize(const LoopKeyframe& keyframe);
  /// Stores a keyframe (descriptor computed once here). Returns false on an unusable cloud.
  bool addKeyframe(const LoopKeyframe& keyframe);
  /// search_frame map: replaces the stored keyframes' poses by the back-end's newest estimates
  /// (keyframes not named keep theirs), so that the stored keyframes and the next queries share
  /// one frame. Poses stored at arrival by the map -> odom of that moment do not: a later
  /// change of map -> odom (the heading found from GNSS, a loop) moves only the newer ones.
  /// Returns how many stored keyframes were moved.
  size_t updatePoses(const std::vector<std::pair<uint64_t, Eigen::Isometry3d>>& poses);

  size_t size() const { return entries_.size(); }
  const LoopDatabaseEntry& entry(size_t index) const { return entries_[index]; }
  const LoopQueryStats& lastStats() const { return stats_; }
  const LoopDetectorParams& params() const { return params_; }
  /// How the stored keyframes' clouds are kept (in memory, on disk, read errors).
  CloudStoreStats cloudStoreStats() const { return clouds_->stats(); }

  /// Phase 1 alone: database indices of the odometry candidates of a query.
  std::vector<size_t> odometryCandidates(const Eigen::Isometry3d& odom_pose,
                                         double accum_distance) const;
  /// Phase 2 alone: best k of the given indices by ring key, then Scan Context distance.
  std::vector<RankedCandidate> rankCandidates(const ScanContext& query,
                                              std::vector<size_t> indices) const;
  /// Place-recognition retrieval: ring-key KD-tree over entries with index < index_limit.
  std::vector<size_t> ringKeyCandidates(const ScanContext& query, size_t index_limit) const;

 private:
  struct Query;
  bool useScanContext() const { return params_.method != "geometric_hierarchy"; }
  bool pclVoxelFilter() const { return params_.voxel_filter == "pcl"; }
  /// Appends the landmark proposal among entries with index < index_limit unless it names a
  /// keyframe already in ranked.
  void addLandmarkCandidate(const Query& query, const PointCloudConstPtr& cloud, size_t index_limit,
                            const std::optional<Eigen::Isometry3d>& odom_pose,
                            std::vector<RankedCandidate>& ranked);
  /// Seeds of the coarse GICP stage for one candidate.
  std::vector<Eigen::Isometry3d> seedsFor(const RankedCandidate& candidate,
                                          const std::optional<Eigen::Isometry3d>& odom_pose) const;
  /// Downsamples the query cloud, verifies the ranked candidates and records the stats.
  std::optional<DetectedLoop> prepareAndVerify(Query& query,
                                               const std::vector<RankedCandidate>& ranked,
                                               const PointCloudConstPtr& cloud,
                                               const std::optional<Eigen::Isometry3d>& odom_pose,
                                               double accum_distance);
  std::optional<DetectedLoop> verify(const Query& query, const std::vector<RankedCandidate>& ranked,
                                     const std::optional<Eigen::Isometry3d>& odom_pose,
                                     double accum_distance);
  std::optional<DetectedLoop> verifyCandidate(const Query& query, const RankedCandidate& candidate,
                                              Eigen::Isometry3d guess,
                                              const std::optional<Eigen::Isometry3d>& odom_pose,
                                              double accum_distance);
  /// Correlative coarse stage + fine stage for one candidate (odometry mode).
  std::optional<DetectedLoop> verifyCorrelative(const Query& query,
                                                const RankedCandidate& candidate,
                                                const Eigen::Isometry3d& odom_pose,
                                                double accum_distance);
  /// Fine registration from guess and the checks shared by both coarse stages.
  std::optional<DetectedLoop> fineStage(const Query& query, const RankedCandidate& candidate,
                                        const Eigen::Isometry3d& guess,
                                        const std::optional<Eigen::Isometry3d>& odom_pose,
                                        double accum_distance, CandidateOutcome& outcome,
                                        const Eigen::Vector3d* correlative_peak);
  std::optional<DetectedLoop> rejectCandidate(CandidateOutcome& outcome, const char* verdict,
                                              int& counter);
  const BevLikelihoodField& fieldOf(size_t index);
  bool useCorrelative(const std::optional<Eigen::Isometry3d>& odom_pose) const;
  Matrix6d informationFromFitness(double fitness) const;
  bool consistentWithOdometry(const LoopDatabaseEntry& target, const Eigen::Isometry3d& transform,
                              const Eigen::Isometry3d& odom_pose, double accum_distance) const;
  void addOdometryNearest(const ScanContext& query, size_t nearest,
                          std::vector<RankedCandidate>& ranked) const;
  size_t indexLimitForDistance(double accum_distance) const;
  /// An entry's cloud decoded, the same pointer while it stays among the recently used (the
  /// registration back-ends keep a target they were given before).
  PointCloudConstPtr entryCloud(size_t index, bool coarse);

  LoopDetectorParams params_;
  Logger logger_;
  std::vector<LoopDatabaseEntry> entries_;
  std::unique_ptr<class DynamicKdIndex> ring_key_index_;
  std::unique_ptr<class DynamicKdIndex> position_index_;
  std::unique_ptr<class LandmarkLoopSource> landmark_source_;  ///< geometric_hierarchy/combined
  std::unique_ptr<Registration> coarse_registration_;
  std::unique_ptr<Registration> fine_registration_;
  LoopQueryStats stats_;
  struct FieldCache;
  std::unique_ptr<FieldCache> field_cache_;
  std::shared_ptr<CloudStore> clouds_;  ///< entries' clouds: 2 x index, coarse 2 x index + 1
  std::list<std::pair<uint64_t, PointCloudConstPtr>> decoded_;  ///< most recent first
  /// The last searched cloud and what was computed from it, for addKeyframe() of the same cloud
  /// right after (process(), the nodelet): descriptor and downsampled cloud not computed twice.
  struct LastQuery {
    PointCloudConstPtr input;
    std::optional<ScanContext> descriptor;
    PointCloudConstPtr stored;
  };
  LastQuery last_query_;
};

/// Fraction of source points (after transform) with a target point within max_distance.
double overlapRatio(const PointCloud& source, const PointCloud& target,
                    const Eigen::Isometry3d& transform, double max_distance);

/// Voxel-grid downsampling that drops non-finite points (leaf <= 0: only the NaN filter);
/// voxelCentroids, or pcl::VoxelGrid when use_pcl (the same voxels and centroids).
PointCloudPtr downsampleForLoop(const PointCloud& cloud, double leaf, bool use_pcl = false);

}  // namespace osm_graph_slam
