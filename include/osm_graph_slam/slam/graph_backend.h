#pragma once
// The SLAM back-end core (OSM thesis §3.3.5-3.5, ART-SLAM §3.1.8 and §5.1.5-5.1.6), shared by the
// graph_backend nodelet and the offline runner. Inputs are queued from any thread and never
// dropped while an optimisation runs; update() moves them into the pose graph, adds the OSM
// prior constraints and runs the phased optimisation (doc/backend.md) plus overlap resolution.
#include <Eigen/Geometry>
#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/cloud_store.h"
#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/logger.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/osm/building.h"
#include "osm_graph_slam/slam/backend_params.h"

namespace osm_graph_slam {

class EnuConverter;
struct BackendQueues;
struct BackendState;
class OsmAssociation;
class BuildingConstraints;

struct KeyframeInput {
  uint64_t id = 0;
  /// The drive it belongs to in a multi-session map (slam/session_merge.h); a run of its own is
  /// session id 0. A session's keyframes form one odometry chain with its own GNSS bias and
  /// odometry scale; sessions are joined by loops and the buildings they share.
  uint32_t session = 0;
  double stamp = 0.0;
  Eigen::Isometry3d odom_pose = Eigen::Isometry3d::Identity();  ///< base_link in odom
  double accum_distance = 0.0;
  double odom_fitness = -1.0;  ///< fitness of the match that made it (< 0: unknown)
  /// That match's Hessian (RegistrationResult::hessian: left perturbation in the previous
  /// keyframe's frame, translation then rotation); zero when unknown.
  Matrix6d odom_hessian = Matrix6d::Zero();
  /// [m] that match's offset from the motion model's prediction (TrackResult), zero if unknown.
  Eigen::Vector3d odom_prediction_error = Eigen::Vector3d::Zero();
  /// The tracker re-anchored it on a guess after failed matches: a weak odometry edge.
  bool reanchored = false;
  PointCloudConstPtr cloud;  ///< filtered cloud in base_link (may be null)
  /// Roll and pitch of base_link against gravity (an IMU), if known [rad].
  std::optional<Eigen::Vector2d> gravity_roll_pitch;
  /// Where GNSS puts base_link at this keyframe's stamp, in the map frame (ENU from the map
  /// origin) [m], if known. The first keyframe is fixed there: the origin is the first fix, and
  /// when the first scans never became keyframes (dropped, empty) the vehicle has moved since.
  std::optional<Eigen::Vector2d> gnss_position;
  /// [m] that fix's horizontal standard deviation, when the receiver reports it: the first
  /// keyframe is held there with it (else with anchor_std_xy).
  std::optional<double> gnss_std;
  /// [m] the fix's altitude in the map frame (ENU up from the map origin, the first fix), if
  /// known: evidence with gnss_altitude_std > 0.
  std::optional<double> gnss_altitude;
  /// [rad] base_link's yaw from an INS at this keyframe's stamp, if known: its changes between
  /// keyframes are evidence with GnssParams::ins_heading_std > 0.
  std::optional<double> ins_yaw;
  /// The floor plane (a, b, c, d) under base_link, if the floor detector found one (it may also
  /// come later through addFloor()).
  std::optional<Eigen::Vector4d> floor;
};

struct LoopClosureInput {
  uint64_t from_id = 0;                                             ///< current keyframe
  uint64_t to_id = 0;                                               ///< earlier keyframe
  Eigen::Isometry3d relative_pose = Eigen::Isometry3d::Identity();  ///< from in to's frame
  Matrix6d information = Matrix6d::Identity();
};

/// What one update() did (for logs, status topics and tests).
struct BackendUpdateReport {
  size_t keyframes_added = 0, loops_added = 0, loops_rejected = 0;
  /// Ids skipped between this update's keyframes and the previous ones: keyframes the tracker
  /// made that never arrived (an input queue overflowed); odometry bridges the gap.
  size_t keyframes_missing = 0;
  size_t gnss_gated = 0;  ///< fixes kept out by the innovation gate
  size_t global_priors = 0, global_rejected = 0;
  size_t building_edges = 0, buildings_added = 0;
  /// Local matches tried, and rejected (no visible wall, or fitness / matched below limits).
  size_t local_attempts = 0, local_unseen = 0, local_rejected = 0;
  size_t building_edges_gated = 0;  ///< removed by the consistency gate
  size_t osm_reassociated = 0;      ///< keyframes matched again after the OSM datum moved
  size_t overlap_iterations = 0, overlap_edges = 0, overlaps_remaining = 0;
  size_t overlaps_projected = 0;  ///< pairs the edges left, cleared by moving one building
  size_t shared_walls = 0;        ///< building pairs tied by a shared wall in this update
  /// Floor plane-pair edges added; consecutive floors not tied because the slope changed or
  /// they lie too far apart (along the path, or in time: stamped before the previous one).
  size_t floor_edges = 0, floor_slope_changes = 0, floor_gaps = 0;
  bool heading_initialized_now = false;
  /// When the heading was just found by global matching (no IMU heading): the keyframe, the pose
  /// the match gave it from the OSM map alone (map frame), the rotation applied to the trajectory
  /// and the match's fitness. Measures "the first pose from the map alone" against a fix.
  struct HeadingFromMap {
    uint64_t keyframe_id = 0;
    Pose2 matched_pose;
    double rotation = 0.0;  ///< [rad]
    double fitness = 0.0;
  };
  std::optional<HeadingFromMap> heading_from_map;
  OptimizationResult phase1, phase2, joint, overlap;
  bool optimized = false;
  /// A windowed update (optimization_window): the oldest keyframe left free; nullopt = a full
  /// batch. full_batch_for_loop: the window was followed by a full batch because a new loop to a
  /// held keyframe still disagreed (window_loop_chi2).
  std::optional<uint64_t> window_start;
  bool full_batch_for_loop = false;
  double total_ms = 0.0;
  /// Where total_ms went [ms]: OSM matching (association and re-association) and each
  /// optimisation phase, summed over every time the update ran it (the consistency gate repeats
  /// phase 2, a re-association all phases). Adds up (StageMs::operator+=) over updates.
  struct StageMs {
    double osm = 0.0, phase1 = 0.0, phase2 = 0.0, joint = 0.0, overlaps = 0.0;
    StageMs& operator+=(const StageMs& o) {
      osm += o.osm, phase1 += o.phase1, phase2 += o.phase2, joint += o.joint;
      overlaps += o.overlaps;
      return *this;
    }
  } stage_ms;
};

struct KeyframeState {
  uint64_t id = 0;
  uint32_t session = 0;  ///< as received (KeyframeInput)
  double stamp = 0.0;
  Eigen::Isometry3d odom_pose = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d map_pose = Eigen::Isometry3d::Identity();
  double accum_distance = 0.0;
  double odom_fitness = -1.0;
  Matrix6d odom_hessian = Matrix6d::Zero();                         ///< as received (KeyframeInput)
  Eigen::Vector3d odom_prediction_error = Eigen::Vector3d::Zero();  ///< as received
  bool reanchored = false;  ///< linked by a weak odometry edge (the tracker re-anchored it)
  std::optional<Eigen::Vector2d> gravity_roll_pitch;  ///< as received (IMU)
  std::optional<Eigen::Vector4d> floor;               ///< in base_link, as received
  std::optional<Eigen::Vector2d> gnss_position;       ///< as received (KeyframeInput), for dumps
  std::optional<double> gnss_std;                     ///< as received
  std::optional<double> gnss_altitude;                ///< as received
  std::optional<double> ins_yaw;                      ///< as received
  /// Filtered cloud in base_link as received, kept in the back-end's CloudStore (within its
  /// quantisation; load() reads a spilled one back from disk).
  StoredCloud cloud;
  std::vector<LineSegment2> segments;  ///< base_link
  bool osm_processed = false;
  bool has_global_prior = false;
  bool has_attitude = false;                ///< a roll/pitch prior (IMU, or odometry's) was added
  bool floor_tied = false;                  ///< a floor edge ties it to a neighbour's floor
  std::optional<Pose2> matched_with_datum;  ///< the OSM datum when its buildings were matched
};

/// A building as the back-end knows it: the OSM prior and the current estimate.
struct BuildingState {
  Building prior;          ///< as received (ENU)
  Pose2 pose;              ///< current estimate of the reference pose
  Polygon2 local_outline;  ///< outline in the building frame (prior pose⁻¹ · outline)
  int vertex_id = -1;
  size_t observations = 0;                   ///< robot↔building edges
  std::optional<double> last_edge_distance;  ///< path distance of its newest edge's keyframe
  uint32_t last_edge_session = 0;            ///< the session of that keyframe
  /// [m], [rad] the estimate's deviations given the trajectory (the larger axis of x, y), when
  /// computed
  /// (GraphBackend::estimateBuildingUncertainty).
  std::optional<double> sigma_xy, sigma_theta;
  /// The prior with outline, reference pose and segments moved to the current estimate.
  Building corrected() const;
};

/// One robot↔building edge in the graph: the building's pose seen from the keyframe.
struct BuildingObservation {
  uint64_t keyframe = 0;
  int64_t building = 0;
  Pose2 measurement;            ///< planar(keyframe)⁻¹ · building
  Eigen::Matrix3d information;  ///< in the building's axes
};

/// How the graph is solved in map tiles (GraphBackend::optimizeInTiles).
struct TileSolveParams {
  double tile_size = 500.0;  ///< [m] square tiles of the map frame
  int max_sweeps = 8;        ///< over every tile
  /// [m] stop once no keyframe or building moved more than this in a sweep.
  double tolerance = 0.005;
};

/// What optimizeInTiles did.
struct TileSolveReport {
  size_t tiles = 0;
  int sweeps = 0;
  double last_sweep_max_move = 0.0;  ///< [m]
  size_t largest_tile_keyframes = 0;
  double total_ms = 0.0;
  double slowest_tile_ms = 0.0;
};

/// map -> odom that puts the first keyframe at `position` (default: the map origin) with the
/// given ENU yaw (or with odometry's yaw when unknown), keeping odometry's roll and pitch.
Eigen::Isometry3d initialMapToOdom(const Eigen::Isometry3d& first_odom_pose,
                                   std::optional<double> yaw,
                                   const Eigen::Vector2d& position = Eigen::Vector2d::Zero());

class GraphBackend {
 public:
  explicit GraphBackend(const GraphBackendParams& params = {},
                        std::shared_ptr<const Logger> logger = nullptr);
  ~GraphBackend();

  // --- inputs: thread-safe, cheap (queued until update()) ------------------------------------
  void setOrigin(double lat, double lon, double alt);
  bool hasOrigin() const;
  /// ENU yaw of the first keyframe (e.g. from an IMU), if the heading is not known yet: the
  /// trajectory so far is rotated about the origin. Ignored once the heading is set.
  void setInitialHeading(double yaw);
  /// ENU yaw of the first keyframe of a session other than the first one (a multi-session map):
  /// it starts there, at its first GNSS fix. Call before that session's keyframes arrive.
  void setSessionHeading(uint32_t session, double yaw);
  /// A session whose start is unknown in the map (resumed mapping before the global localiser
  /// placed it, no GNSS): its keyframes are mapped on their own where odometry puts them from the
  /// origin, are not matched with OSM buildings (the match would be a guess), and its first loop
  /// to a placed session moves it there rigidly (placeSession). Call before its keyframes arrive.
  void setSessionUnplaced(uint32_t session);
  /// Whether the session is still waiting for that loop.
  bool sessionPlaced(uint32_t session) const;
  /// Keyframes of a saved map (resumed mapping) set to their saved poses and held there: kept as
  /// they were saved, not re-estimated; the buildings they observe stay free. Unknown ids are
  /// skipped; returns how many were held.
  size_t holdKeyframesAt(const std::map<uint64_t, Eigen::Isometry3d>& poses);
  void addKeyframe(KeyframeInput keyframe);
  void addLineSegments(uint64_t keyframe_id, std::vector<LineSegment2> segments);
  /// The floor plane (a, b, c, d) under a keyframe's base_link (floor_detection).
  void addFloor(uint64_t keyframe_id, const Eigen::Vector4d& coeffs);
  /// Buildings (ENU filled) answering a query of radius query_radius around query_center.
  void addBuildings(std::vector<Building> buildings, const Eigen::Vector2d& query_center,
                    double query_radius);
  void addLoopClosure(const LoopClosureInput& loop);

  // --- processing ------------------------------------------------------------------------------
  /// Moves queued inputs into the graph and, if anything changed (or force), optimises.
  BackendUpdateReport update(bool force_optimize = false);

  // --- outputs: thread-safe snapshots --------------------------------------------------------
  std::vector<KeyframeState> keyframes() const;
  size_t numKeyframes() const;
  /// Keyframe ids skipped so far (made by the tracker, never received); see BackendUpdateReport.
  size_t missingKeyframes() const;
  std::optional<KeyframeState> latestKeyframe() const;
  /// map -> odom, so that map_pose(latest) = mapToOdom * odom_pose(latest).
  Eigen::Isometry3d mapToOdom() const;
  Trajectory trajectory() const;  ///< corrected keyframe poses (map)
  /// (id, corrected pose in map) of every keyframe in the graph, in id order.
  std::vector<std::pair<uint64_t, Eigen::Isometry3d>> keyframeMapPoses() const;
  Trajectory odomTrajectory() const;  ///< the same keyframes as odometry saw them
  std::vector<BuildingState> buildings() const;
  /// outline_geo filled when the origin is set; tagged with the number of robot↔building edges
  /// and of keyframes and sessions they come from (kObservationsTag, kKeyframesTag,
  /// kSessionsTag) and, once estimated, the
  /// estimate's deviations (kSigmaXyTag, kSigmaThetaTag).
  std::vector<Building> correctedBuildings() const;
  /// Solves the graph tile by tile instead of at once (a city's graph in bounded pieces): a
  /// keyframe belongs to the tile holding its position, a building to the one holding its
  /// reference corner; each tile's keyframes and buildings are optimised (all phases) with the
  /// rest of the graph held, the tiles in checkerboard order (tiles of one colour share no
  /// border), sweeps repeated until nothing moves more than the tolerance. Queued inputs are
  /// taken in first (update() without optimising). The joint solve is update(true).
  TileSolveReport optimizeInTiles(const TileSolveParams& params);
  /// The deviations of every observed building's estimate given the trajectory (robot poses
  /// held; one factorisation). False with the reason (logged) when they have no unique solution.
  bool estimateBuildingUncertainty();
  std::vector<BuildingObservation> buildingObservations() const;  ///< edges still in the graph
  PoseGraph graphSnapshot() const;
  std::vector<LoopClosureInput> loopClosures() const;  ///< the ones added to the graph
  std::optional<EnuConverter> origin() const;
  /// The heading the run started from (parameters or setInitialHeading), if one was known.
  std::optional<double> startHeading() const;
  const GraphBackendParams& params() const { return params_; }
  size_t pendingInputs() const;
  /// How the keyframe clouds are kept (in memory, on disk, read errors).
  CloudStoreStats cloudStoreStats() const;

  /// Vertex id of a building's SE2 vertex (robot keyframe k has vertex id k).
  static constexpr int kBuildingVertexBase = 1 << 30;
  /// Vertex id of the OSM datum (osm_datum_std_xy > 0); keyframe ids stay below it.
  static constexpr int kOsmDatumVertex = kBuildingVertexBase - 1;
  /// Vertex id of the GNSS bias of time window k (gnss_bias_std > 0): kGnssBiasVertexTop − k.
  static constexpr int kGnssBiasVertexTop = kOsmDatumVertex - 1;
  /// Vertex id of the odometry scale of path window k (odometry_scale_window > 0):
  /// kScaleVertexTop − k (below every GNSS bias window of a drive shorter than five years).
  static constexpr int kScaleVertexTop = kGnssBiasVertexTop - (1 << 24);
  /// GNSS bias and odometry scale windows per session: session s's window k is vertex
  /// kGnssBiasVertexTop − s·kSessionWindows − k (45 h of 10 s bias windows, 1,600 km of 100 m
  /// scale windows; later windows share the last one).
  static constexpr int kSessionWindows = 1 << 14;
  /// Sessions with vertices of their own below kScaleVertexTop; keyframe ids stay below
  /// kKeyframeIdLimit.
  static constexpr int kMaxSessions = 1 << 10;
  static constexpr int kKeyframeIdLimit = kScaleVertexTop - kMaxSessions * kSessionWindows;
  /// The estimated offset of the OSM map as a whole (ENU), when the datum is on and in the graph.
  std::optional<Pose2> osmDatum() const;
  /// The estimated odometry scale of each path window, in path order (empty when
  /// odometry_scale_window is 0).
  std::vector<double> odometryScales() const;

 private:
  /// Logs once when an estimated odometry scale is more than kOdometryScaleWarning from 1.
  void reportOdometryScale();
  /// OSM association of the keyframes not matched yet, timed into report.stage_ms.osm.
  void processOsm(BackendUpdateReport& report);
  /// 1 %: twice what a KITTI HDL-64E's vertical-angle bias gives (0.46 % in the simulator).
  static constexpr double kOdometryScaleWarning = 0.01;
  /// [m] a further session's start height: its fix's altitude (or odometry's) is not the map's
  /// vertical datum; loops, the floors and the fixes' altitude settle it.
  static constexpr double kSessionStartStdZ = 2.0;
  static constexpr double kUnheldStd = 1e3;  ///< a prior's deviation that holds nothing
  /// GNSS prior edges on keyframes (gnss_prior_std > 0 and the heading known).
  bool gnssPriors() const;
  /// The innovation gate (GnssParams::gnss_innovation_gate); counts what it keeps out.
  bool gnssFixPassesGate(const KeyframeInput& in, const KeyframeState& kf);
  /// ... with the fixes' altitude as evidence too (gnss_altitude_std > 0).
  bool gnssAltitude() const;
  /// The keyframe's GNSS prior edge (with its bias vertex when gnss_bias_std > 0).
  void addGnssPrior(const KeyframeInput& in);
  /// The keyframe's INS heading-change edge (ins_heading_std > 0).
  void addInsHeadingChange(const KeyframeInput& in);
  /// gnss_prior_std and gnss_bias_std scale for the keyframe's fix: its reported deviation over
  /// their combined deviation (gnss_reported_accuracy), else 1.
  double gnssAccuracyScale(const KeyframeInput& in) const;
  void flushKeyframes(BackendUpdateReport& report);
  void attachSegments(std::map<uint64_t, std::vector<LineSegment2>> segments);
  bool acceptable(const KeyframeInput& in) const;  ///< in order and in range, else logged once
  void insertKeyframe(const KeyframeInput& in, StoredCloud cloud);
  void countMissing(uint64_t id, BackendUpdateReport& report);  ///< ids skipped before `id`
  /// The first loop from the pass after a jump back in time to an earlier pass moves that pass
  /// to where the loop says (its provisional odometry link follows).
  void placeAfterRestart(const LoopClosureInput& loop);
  void anchorFirstKeyframe(const KeyframeInput& in, KeyframeState& kf);
  /// The first keyframe of a further session: at its GNSS fix with its start heading, free.
  void anchorSessionStart(const KeyframeInput& in, KeyframeState& kf);
  /// The first loop between an unplaced session and a placed one moves the unplaced session
  /// rigidly to where the loop puts it (its odometry chain kept as it is).
  void placeSession(const LoopClosureInput& loop);
  void linkToPrevious(const KeyframeInput& in, KeyframeState& kf, const KeyframeState& prev);
  void addKeyframePriors(const KeyframeInput& in, KeyframeState& kf);  ///< GNSS, gravity
  void dropOrphanSegments();
  void flushLoops(BackendUpdateReport& report);
  void flushBuildings(BackendUpdateReport& report);
  void flushFloors(BackendUpdateReport& report);
  void linkFloor(KeyframeState& kf, BackendUpdateReport& report);
  /// The three phases over every vertex, or (window_start) with the keyframes before it and the
  /// buildings none of the free keyframes observes held fixed. phase1 false: from phase 2 on,
  /// the robots where the last joint phase left them (only building edges changed since).
  void optimizePhases(BackendUpdateReport& report, std::optional<uint64_t> window_start,
                      bool phase1 = true);
  /// Translates every free keyframe and building (and the datum) by the mean residual of the
  /// GNSS fixes: the coarse step of optimizeInTiles.
  void shiftMapToFixes();
  /// The phases with the vertices `held` fixed (freed again at the end, see release()).
  void runPhases(BackendUpdateReport& report, const std::vector<int>& held, bool phase1);
  /// The oldest keyframe a routine update frees (optimization_window), nullopt: all of them.
  std::optional<uint64_t> windowStart() const;
  /// Loops added since the last check that reach from the window to a held keyframe and still
  /// disagree by more than window_loop_chi2.
  bool newLoopDisagrees(uint64_t window_start);
  void updateMapToOdom();

  GraphBackendParams params_;
  std::shared_ptr<const Logger> logger_;

  mutable std::mutex queue_mutex_;
  std::unique_ptr<BackendQueues> pending_;
  mutable std::mutex state_mutex_;
  std::unique_ptr<BackendState> state_;
  std::unique_ptr<OsmAssociation> osm_;               ///< robot<->building edges per OSM mode
  std::unique_ptr<BuildingConstraints> constraints_;  ///< gate, shared walls, overlaps
  std::shared_ptr<CloudStore> clouds_;                ///< the keyframes' clouds
  std::atomic<uint64_t> next_cloud_key_{0};           ///< store keys, in arrival order
};

}  // namespace osm_graph_slam
