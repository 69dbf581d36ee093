#pragma once
// Many drives, one map: the graph dumps of several drives (offline_slam --dump) joined into one
// GraphBackend. Each drive is a session (KeyframeInput::session): its own odometry chain, GNSS
// bias and odometry scale; the drives share one OSM datum and one vertex per building, so every
// building is corrected by all the drives that saw it. Inter-session loops are found by the
// loop detector (Scan Context, then the same verification as within a drive) between each
// drive's keyframes and those of the drives before it, at their poses in the joint map.
// doc/fleet.md describes the data flow and the figures.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/graph_dump.h"

namespace osm_graph_slam {

struct SessionMergeParams {
  /// Keyframes between updates while the sessions are added (as the offline pipeline).
  int optimize_every = 10;
  /// [m] two drives placed by their own fixes are as uncertain relative to each other as two
  /// keyframes this far apart on one drive: the loop detector's search radius and odometry
  /// tolerances (LoopDetectorParams *_per_meter) are taken at this path gap. 200 m: a 20 m
  /// radius and 4 m / 0.09 rad tolerances, twice a consumer receiver's bias.
  double session_gap = 200.0;
  /// Inter-session loop search (off: the sessions share only buildings and the datum).
  bool inter_session_loops = true;
  /// [m] an inter-session loop is refused when where it puts its keyframe relative to the joint
  /// map differs by more than this from what its neighbours (loops between the same two
  /// sessions within loop_consistency_window seconds) say: the drives' relative placement
  /// error changes slowly, an aliased match (a facade period along a straight street) jumps.
  /// Measured: correct loops within 0.3 m of their neighbours, aliased ones 1.5 m (16 drives).
  double loop_consistency_distance = 0.8;
  double loop_consistency_window = 20.0;    ///< [s] of the newer session's keyframes
  int loop_consistency_min_neighbours = 3;  ///< fewer: the loop is kept (nothing to judge by)
  /// The buildings' marginal deviations after the merge (GraphBackend::
  /// estimateBuildingUncertainty): each corrected building says how sure the map is of it.
  bool building_uncertainty = true;
  /// Solve in map tiles (GraphBackend::optimizeInTiles) instead of one joint solve; the
  /// tile size 0: joint.
  TileSolveParams tiles{0.0};
};

/// Indices of the loops whose offset from the map (where the loop puts its `from` keyframe
/// minus where `poses` has it) differs by more than loop_consistency_distance from the median
/// offset of the other loops between the same sessions within loop_consistency_window seconds
/// (`stamps` of the `from` keyframes).
std::vector<size_t> inconsistentLoops(const std::vector<LoopClosureInput>& loops,
                                      const std::map<uint64_t, Eigen::Isometry3d>& poses,
                                      const std::map<uint64_t, double>& stamps,
                                      const SessionMergeParams& params);

/// The merged id of keyframe `id` of session `session` (ids of a session stay below the stride).
constexpr uint64_t kSessionIdStride = uint64_t{1} << 20;
inline uint64_t mergedKeyframeId(uint32_t session, uint64_t id) {
  return session * kSessionIdStride + id;
}

struct SessionSummary {
  std::string name;
  uint32_t session = 0;
  size_t keyframes = 0;
  size_t keyframes_without_cloud = 0;
  size_t inter_session_loops = 0;  ///< loops from its keyframes to earlier sessions
};

struct SessionMergeReport {
  std::vector<SessionSummary> sessions;
  size_t keyframes = 0;
  std::vector<LoopClosureInput> inter_session_loops;
  size_t loop_queries = 0;
  size_t loops_inconsistent = 0;  ///< verified, then refused by the consistency test
  /// Observed buildings by the number of sessions that observed them (robot↔building edges).
  std::map<size_t, size_t> buildings_by_sessions;
  double add_ms = 0.0, loops_ms = 0.0, optimize_ms = 0.0, uncertainty_ms = 0.0;
  BackendUpdateReport last_update;
  std::optional<TileSolveReport> tiles;  ///< when solved in tiles
};

class SessionMerge {
 public:
  SessionMerge(const GraphBackendParams& backend, const LoopDetectorParams& loops,
               const SessionMergeParams& params = {},
               std::shared_ptr<const Logger> logger = nullptr);
  ~SessionMerge();

  /// Adds a drive (its clouds loaded for the loop search, loadDumpClouds). The first session's
  /// origin is the map's; the others' GNSS fixes and buildings are moved to it. False with the
  /// reason when the dump cannot join (no keyframe, no origin when the map has one, too many
  /// keyframes or sessions).
  bool addSession(const std::string& name, GraphDump dump, std::string* error);
  size_t numSessions() const { return sessions_.size(); }

  /// Replays every session into the back-end, searches the inter-session loops, optimises.
  SessionMergeReport merge();

  const GraphBackend& backend() const { return *backend_; }
  /// Session of a merged keyframe id.
  static uint32_t sessionOf(uint64_t merged_id) {
    return static_cast<uint32_t>(merged_id / kSessionIdStride);
  }

 private:
  struct Session {
    std::string name;
    GraphDump dump;  ///< ids merged, in the map's frame
  };
  /// Searches each session's keyframes against those of the sessions before it.
  std::vector<LoopClosureInput> findInterSessionLoops(SessionMergeReport& report);
  std::map<size_t, size_t> buildingsBySessions() const;

  GraphBackendParams backend_params_;
  LoopDetectorParams loop_params_;
  SessionMergeParams params_;
  std::shared_ptr<const Logger> logger_;
  std::unique_ptr<GraphBackend> backend_;
  std::vector<Session> sessions_;
  std::optional<Eigen::Vector3d> origin_;  ///< lat, lon, alt of the map frame
};

}  // namespace osm_graph_slam
