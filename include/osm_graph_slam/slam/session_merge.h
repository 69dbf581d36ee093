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
#include "osm_graph_slam/slam/inter_session_loops.h"

namespace osm_graph_slam {

struct SessionMergeParams {
  /// Keyframes between updates while the sessions are added (as the offline pipeline).
  int optimize_every = 10;
  /// Inter-session loop search (off: the sessions share only buildings and the datum).
  bool inter_session_loops = true;
  InterSessionLoopParams loop_search;
  /// The buildings' marginal deviations after the merge (GraphBackend::
  /// estimateBuildingUncertainty): each corrected building says how sure the map is of it.
  bool building_uncertainty = true;
  /// Solve in map tiles (GraphBackend::optimizeInTiles) instead of one joint solve; the
  /// tile size 0: joint.
  TileSolveParams tiles{0.0};
};

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
