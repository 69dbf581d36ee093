#pragma once
// The back-end's state behind GraphBackend, shared with the modules it delegates to by concept
// (osm_association: robot<->building edges per OSM mode; building_constraints: gate, shared
// walls, overlaps). Internal to src/slam/: not an installed header.
#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "osm_graph_slam/common/sequence_gaps.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

/// Inputs queued by the thread-safe add*() calls until the next update().
/// A keyframe waiting for update(): its cloud already encoded in the back-end's store (under a
/// key of its own until the keyframe is accepted), the input's cloud pointer released.
struct PendingKeyframe {
  KeyframeInput input;
  StoredCloud cloud;
};

struct BackendQueues {
  std::deque<PendingKeyframe> keyframes;
  std::map<uint64_t, std::vector<LineSegment2>> segments;
  std::map<uint64_t, Eigen::Vector4d> floors;
  std::deque<LoopClosureInput> loops;
  struct BuildingBatch {
    std::vector<Building> buildings;
    Eigen::Vector2d center;
    double radius;
  };
  std::deque<BuildingBatch> buildings;
};

/// A robot<->building edge still in the graph, kept for the gate and re-association.
struct BuildingEdgeRecord {
  int edge_id;
  uint64_t keyframe;
  int64_t building;
  Pose2 z;
  Eigen::Matrix3d information;
};

struct BackendState {
  PoseGraph graph;
  std::map<uint64_t, KeyframeState> keyframes;
  std::map<int64_t, BuildingState> buildings;
  std::map<uint64_t, std::vector<LineSegment2>> early_segments;  ///< keyframe not yet inserted
  std::map<uint64_t, Eigen::Vector4d> early_floors;              ///< keyframe not yet inserted
  std::deque<LoopClosureInput> early_loops;                      ///< current keyframe not yet in
  std::vector<std::pair<Eigen::Vector2d, double>> coverage;      ///< answered OSM queries
  std::optional<EnuConverter> origin;
  Eigen::Isometry3d map_to_odom = Eigen::Isometry3d::Identity();
  bool heading_initialized = false;
  std::optional<double> initial_yaw;    ///< known ENU yaw of the first keyframe
  bool heading_known_at_start = false;  ///< initial_yaw was known when the first keyframe came
  size_t gnss_priors = 0;               ///< GNSS prior edges added
  size_t gnss_gated = 0;                ///< fixes the innovation gate kept out
  /// GNSS priors hold the trajectory (at least two fixes; one origin anchors no better than the
  /// soft anchor): building and datum priors created from then on take their tighter deviations
  /// (OsmPriorParams::building_prior_std_xy vs ..._without_gnss).
  bool gnssAnchored() const { return gnss_priors >= 2; }
  /// The map's weighting for gnssAnchored() or not (OsmPriorParams: the map's deviations,
  /// datum kernel and re-association distance, each with a ..._without_gnss twin).
  struct MapWeighting {
    double building_std_xy;
    double datum_std_xy;  ///< <= 0: no datum
    std::string datum_kernel;
    double datum_reassociate_distance;
  };
  MapWeighting mapWeighting(const OsmPriorParams& p) const;
  int next_building_vertex = GraphBackend::kBuildingVertexBase;
  /// What one session (a drive of a multi-session map; a single run has session id 0) keeps of its
  /// own: its chain's newest keyframe, its GNSS bias and odometry scale windows, the GNSS gate's
  /// and the INS heading edges' last keyframes, its floor chain. Drives share buildings and the
  /// OSM datum, never a receiver's bias or an odometry's scale.
  struct Session {
    uint64_t newest_keyframe = 0;
    std::optional<double> gnss_bias_start;   ///< stamp where GNSS bias window 0 starts
    std::map<int, int> gnss_bias_vertices;   ///< window -> its bias vertex
    std::map<int, double> gnss_bias_scales;  ///< window -> its deviation's scale
    std::map<int, int> scale_vertices;       ///< odometry scale window -> its scale vertex
    /// [m] odometry path length at the last fix that passed the gate (none yet: nullopt)
    std::optional<double> gnss_passed_at;
    /// accum_distance -> (keyframe, INS yaw) of the keyframes with an INS heading
    std::map<double, std::pair<uint64_t, double>> ins_headings;
    std::optional<uint64_t> last_floor_keyframe;  ///< the newest keyframe with a floor
  };
  std::map<uint32_t, Session> sessions;
  std::map<uint32_t, double> session_start_yaw;  ///< known ENU yaw of a session's first keyframe
  /// Sessions whose map poses are a guess (GraphBackend::setSessionUnplaced) until their first
  /// loop to a placed session (GraphBackend::placeSession).
  std::set<uint32_t> unplaced_sessions;
  /// The session of a keyframe in the graph (session id 0 when unknown).
  uint32_t sessionOf(uint64_t keyframe) const;
  std::vector<BuildingEdgeRecord> building_edges;  ///< robot<->building edges still in the graph
  std::vector<LoopClosureInput> loops;
  size_t loops_checked_by_window = 0;  ///< loops[0..n) were checked after a windowed update
  bool dirty = false;
  double latest_stamp = 0.0;
  SequenceGaps keyframe_ids;  ///< ids of accepted keyframes: those skipped were never received
  /// After the time jumped back (a looped bag), the new pass hangs from the old pass's end by
  /// provisional odometry edges until its first loop to the old pass places it there
  /// (GraphBackend::placeAfterRestart).
  struct UnplacedPass {
    uint64_t first_id = 0;
    std::vector<int> link_edges;  ///< the provisional edges (each optimisation level)
  };
  std::optional<UnplacedPass> unplaced;

  /// An unobserved building stays at its prior (unobserved_buildings_fixed).
  static bool heldAtPrior(const BuildingState& b, const OsmPriorParams& p) {
    return p.unobserved_buildings_fixed && b.observations == 0;
  }
  /// One more robot<->building edge on b: an observed building is free to move.
  void observed(BuildingState& b, OsmMode mode);
  /// b's vertex, created with its prior (relative to the OSM datum) on first use.
  int buildingVertex(BuildingState& b, OsmMode mode, const OsmPriorParams& p);
  /// Where a building is expected before anything observed it: its prior moved by the datum.
  Pose2 predictedPose(const BuildingState& b, const OsmPriorParams& p) const;
  /// Index of the session's GNSS bias window holding stamp (0 before its first fix or for a bad
  /// stamp; at most GraphBackend::kSessionWindows - 1).
  static int gnssBiasWindow(const Session& session, double stamp, const GnssParams& p);
  /// Index of the odometry scale's path window holding accum_distance (0 for a bad length; at
  /// most GraphBackend::kSessionWindows - 1).
  static int odometryScaleWindow(double accum_distance, const OdometryEdgeParams& p);
  /// The GNSS bias vertex of the session's window holding stamp (gnss_bias_std > 0), created on
  /// first use with deviation gnss_bias_std x scale (the first fix of the window decides the
  /// scale) and tied to the session's previous window by the Gauss-Markov process of the bias
  /// over its deviation.
  int gnssBiasVertex(uint32_t session, double stamp, const GnssParams& p, double scale = 1.0);
  /// The odometry scale vertex of the session's path window holding accum_distance (created on
  /// first use: a prior around 1 for its first window, a random walk from the previous one).
  int odometryScaleVertex(uint32_t session, double accum_distance, const OdometryEdgeParams& p);
  /// The OSM datum: where the map as a whole sits relative to ENU, held at zero by a prior.
  int datumVertex(const OsmPriorParams& p);
  /// The datum's deviation for this run (with or without GNSS priors); <= 0: no datum.
  double datumStdXy(const OsmPriorParams& p) const { return mapWeighting(p).datum_std_xy; }
  /// Whether an answered OSM query covers the position.
  bool covered(const Eigen::Vector2d& position) const;

  /// Fixes a free vertex and notes it in fixed_now (to free again after an update).
  void holdVertex(int vid, std::vector<int>& fixed_now);
  /// Fixes the keyframes and the odometry scales; returns the vertices it fixed.
  std::vector<int> fixRobots();
  /// Fixes the keyframes before window_start, the odometry scales and GNSS biases of windows
  /// (of path, of time) that end before it, and the buildings no keyframe from window_start on
  /// observes; returns the vertices it fixed (to free again after the update).
  std::vector<int> holdOutsideWindow(uint64_t window_start, const OdometryEdgeParams& odometry,
                                     const GnssParams& gnss);
  /// Fixes every keyframe but `free_keyframes`, every building but `free_buildings`, and the
  /// GNSS bias and odometry scale windows none of the free keyframes lies in (a map tile solved
  /// with the rest of the graph held); returns the vertices it fixed.
  std::vector<int> holdOutsideTile(const std::set<uint64_t>& free_keyframes,
                                   const std::set<int64_t>& free_buildings,
                                   const OdometryEdgeParams& odometry, const GnssParams& gnss);
  /// Frees the vertices holdOutsideWindow() fixed, except buildings that must stay at their
  /// prior (the gate may have removed their last observation meanwhile).
  void release(const std::vector<int>& held, const OsmPriorParams& p);
  void readRobotPoses();
  void readBuildingPoses(const OsmPriorParams& p);
  /// Rotates every keyframe by dyaw about the first one (fixed where GNSS put it).
  void rotateTrajectory(double dyaw);
};

// Edge helpers shared by the modules.
RobustKernel kernelNamed(const std::string& name, double width);
/// Information of a 2D match (translation in map axes) re-expressed in the axes of an edge whose
/// error is measured in a frame rotated by `frame_yaw` (the g2o SE2 error convention).
Eigen::Matrix3d rotateInformation(const Eigen::Matrix3d& info_map, double frame_yaw);
/// A unary SE3 measurement that constrains only roll and pitch (the x/y components of the
/// rotation error in the measurement frame, whose yaw is the current estimate's).
Eigen::Isometry3d attitudeMeasurement(const Eigen::Isometry3d& pose, double roll, double pitch);
Matrix6d attitudeInformation(double std_rad);

}  // namespace osm_graph_slam
