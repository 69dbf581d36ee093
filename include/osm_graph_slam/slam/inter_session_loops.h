#pragma once
// Loops between sessions (drives) of one map: the loop detector's Scan Context search and
// verification between a session's keyframe and the keyframes of other sessions, all at their
// poses in the map, plus a test of each loop against its neighbours. merge_sessions runs it over
// whole drives, resumed mapping (slam/map_resume.h) keyframe by keyframe: one mechanism for both.
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

struct InterSessionLoopParams {
  /// [m] two drives placed by their own fixes (or by the global localiser) are as uncertain
  /// relative to each other as two keyframes this far apart on one drive: the loop detector's
  /// search radius and odometry tolerances (LoopDetectorParams *_per_meter) are taken at this
  /// path gap. 200 m: a 20 m radius and 4 m / 0.09 rad tolerances, twice a consumer receiver's
  /// bias.
  double session_gap = 200.0;
  /// [m] a loop is refused when where it puts its keyframe relative to the joint map differs by
  /// more than this from what its neighbours (loops between the same two sessions within
  /// consistency_window seconds) say: the drives' relative placement error changes slowly, an
  /// aliased match (a facade period along a straight street) jumps. Measured: correct loops
  /// within 0.3 m of their neighbours, aliased ones 1.5 m (16 drives).
  double consistency_distance = 0.8;
  double consistency_window = 20.0;    ///< [s] of the newer session's keyframes
  int consistency_min_neighbours = 3;  ///< fewer: the loop is kept (nothing to judge by)
};

/// Indices of the loops whose offset from the map (where the loop puts its `from` keyframe
/// minus where `poses` has it) differs by more than consistency_distance from the median offset
/// of the other loops between the same sessions within consistency_window seconds (`stamps` of
/// the `from` keyframes). `session_of` names a keyframe's session.
std::vector<size_t> inconsistentLoops(const std::vector<LoopClosureInput>& loops,
                                      const std::map<uint64_t, Eigen::Isometry3d>& poses,
                                      const std::map<uint64_t, double>& stamps,
                                      const InterSessionLoopParams& params,
                                      const std::function<uint32_t(uint64_t)>& session_of);

/// The search: keyframes of placed sessions go into the database at their map poses (path
/// distance 0); each query comes at session_gap, so every pair of sessions is searched with the
/// radius and tolerances of that gap.
class InterSessionLoopSearch {
 public:
  InterSessionLoopSearch(const LoopDetectorParams& loops, const InterSessionLoopParams& params,
                         std::shared_ptr<const Logger> logger);
  ~InterSessionLoopSearch();

  void addToDatabase(uint64_t id, const Eigen::Isometry3d& map_pose,
                     const PointCloudConstPtr& cloud);
  /// A verified loop from keyframe `id` (at map_pose) to a database keyframe, if any.
  std::optional<LoopClosureInput> query(uint64_t id, const Eigen::Isometry3d& map_pose,
                                        const PointCloudConstPtr& cloud);
  size_t queries() const { return queries_; }
  size_t databaseSize() const { return database_size_; }
  const InterSessionLoopParams& params() const { return params_; }

 private:
  InterSessionLoopParams params_;
  std::unique_ptr<LoopDetector> detector_;
  size_t queries_ = 0, database_size_ = 0;
};

}  // namespace osm_graph_slam
