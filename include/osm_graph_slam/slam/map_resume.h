#pragma once
// Mapping resumed on a saved map. The saved map's graph (save_map's graph/, a dump_graph folder)
// is replayed into the back-end as its first sessions; the live drive becomes one more session
// (slam/session_merge.h's ids and sessions). Without a GNSS fix the live session is unplaced: it
// maps on its own and is matched with no OSM building until the global localiser (the saved
// map_package/, localization/localizer.h) has placed two of its keyframes consistently with
// odometry. Those two answers become loops to the saved keyframes, which move the session into
// the map (GraphBackend::setSessionUnplaced). From then on every keyframe is searched against
// the saved keyframes (slam/inter_session_loops.h), as merge_sessions searches drives.
// doc/resume_mapping.md describes the data flow and the measurements.
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/inter_session_loops.h"

namespace osm_graph_slam {

struct MapResumeParams {
  /// The saved keyframes stay at their saved poses (GraphBackend::holdKeyframesAt), the frame
  /// the localiser places the live session in; only the buildings and the live session are
  /// estimated. false: the replayed sessions are re-estimated with the live run's parameters,
  /// which need not be theirs (a GNSS-denied run replays a GNSS-aided map without its fixes:
  /// measured, a simulated drive was then placed 95 m off).
  bool hold_saved_map = true;
  /// Global answers that must agree (each pair's relative pose with odometry's) before the
  /// session is placed: one answer can be an aliased place, two that agree with the motion
  /// between them are not.
  int placement_answers = 2;
  /// [m] how far two answers' relative translation may differ from odometry's: this plus
  /// placement_tolerance_per_meter of the path between them (odometry drifts with it).
  double placement_tolerance = 0.5;
  double placement_tolerance_per_meter = 0.02;
  double placement_tolerance_yaw = 0.035;  ///< [rad] 2 deg
  /// How many recent answers a new one is compared with; the agreeing ones must also be more
  /// than half of them (measured: a simulated drive on a long straight street had six answers
  /// at four places, two of them agreeing 130 m from the truth).
  int placement_memory = 6;
  /// Answers that agree can still share one offset (a self-similar junction or street seen
  /// twice): the placement holds only once the keyframes after it that it puts on the saved map
  /// (a saved keyframe within placement_check_radius) have inter-session loops (the loop
  /// detector's own verification) that put them where it does: placement_checks such keyframes,
  /// at least placement_confirm_fraction of them with an agreeing loop, none disagreeing.
  /// Measured: drive 0048 resumed on 0005's map had two agreeing answers 40 m off and no loop;
  /// simulated drives on a procedural city were placed 130 m off at a look-alike junction with
  /// loops at 3 of the next 12 keyframes, while correct placements had loops at nearly every one.
  int placement_checks = 6;
  double placement_confirm_fraction = 0.75;
  double placement_check_radius = 10.0;  ///< [m]
  /// Keyframes a candidate may wait for its checks (it may leave the saved map) before it is
  /// dropped.
  int placement_check_patience = 20;
  /// Deviations of the loops that tie a placed keyframe to the saved one it was registered to.
  double placement_std_xy = 0.1;    ///< [m]
  double placement_std_yaw = 0.01;  ///< [rad]
  InterSessionLoopParams loop_search;
};

struct MapResumeStatus {
  uint32_t session = 0;        ///< the live session's id
  size_t saved_keyframes = 0;  ///< replayed from the saved map
  size_t saved_sessions = 0;
  bool placed = false;
  bool placed_by_gnss = false;  ///< the live session had fixes: GNSS placed it
  /// The localiser tracked the session's first keyframes on the saved map (a hand-over,
  /// slam/localization_handover.h): its poses of them placed it.
  bool placed_by_localizer = false;
  size_t localizer_ties = 0;          ///< keyframes tied by the localiser's poses
  size_t localizer_ties_refused = 0;  ///< ... refused: they disagreed with odometry
  std::optional<uint64_t> placed_at;  ///< the keyframe (graph id) whose answer placed it
  Eigen::Isometry3d placement = Eigen::Isometry3d::Identity();  ///< its map pose then
  size_t global_attempts = 0, global_answers = 0;
  size_t answers_disagreeing = 0;     ///< answers that agreed with no earlier one
  size_t placements_unconfirmed = 0;  ///< agreeing answers the inter-session loops did not confirm
  size_t inter_session_loops = 0, loops_inconsistent = 0;
  double replay_ms = 0.0, global_ms = 0.0, loops_ms = 0.0;
  /// One line for logs and reports ("placed at keyframe ... after N attempts" or "not placed").
  std::string text() const;
};

class MapResume {
 public:
  /// Loads save_map's folder `directory` (map_package/ and graph/) and replays its graph into
  /// `backend`, which must be empty. Null with the reason (a missing or damaged folder, another
  /// package version, a backend that already has keyframes); the backend is then untouched.
  static std::unique_ptr<MapResume> load(const std::string& directory,
                                         const MapResumeParams& params,
                                         const LocalizationParams& localization,
                                         const LoopDetectorParams& loops, GraphBackend& backend,
                                         std::shared_ptr<const Logger> logger, std::string* error);
  ~MapResume();

  uint32_t session() const { return status_.session; }
  /// The graph id of the live session's keyframe `live_id` (the tracker's id).
  uint64_t graphId(uint64_t live_id) const;

  /// Renumbers a live keyframe into the live session (graphId). Call before addKeyframe.
  void renumber(KeyframeInput& keyframe) const;
  /// After the keyframe went to the back-end, before the update that takes it in: the loops it
  /// gives (placement ties, then inter-session loops) for backend.addLoopClosure. The first
  /// keyframe decides whether the session waits for the localiser (no fix the back-end uses)
  /// and tells the back-end so. `localized`: where a localiser tracking on the saved map put
  /// the keyframe (a hand-over): it places the session, no global search needed.
  std::vector<LoopClosureInput> process(
      const KeyframeInput& keyframe, GraphBackend& backend,
      const std::optional<Eigen::Isometry3d>& localized = std::nullopt);
  /// The saved map's localiser (global answers); a hand-over tracks with it before mapping.
  Localizer& localizer() { return *localizer_; }

  const MapResumeStatus& status() const { return status_; }

 private:
  struct Answer {
    uint64_t keyframe;
    Eigen::Isometry3d odom_pose, map_pose;
    double accum_distance;
    uint64_t saved_keyframe;
  };
  MapResume(const MapResumeParams& params, std::shared_ptr<const Logger> logger);
  /// Agreeing answers waiting for an inter-session loop to confirm them.
  struct Candidate {
    std::vector<Answer> answers;          ///< the newest first
    int keyframes = 0;                    ///< keyframes since it was made
    int checks = 0;                       ///< of those, put on the saved map by it
    std::vector<LoopClosureInput> loops;  ///< agreeing inter-session loops found meanwhile
    std::vector<std::pair<uint64_t, Eigen::Isometry3d>> loop_poses;  ///< their keyframes' poses
    std::vector<double> loop_stamps;
  };
  /// What the candidate's checks conclude (nullopt: not yet).
  std::optional<bool> candidateVerdict(const Candidate& c) const;
  std::vector<LoopClosureInput> acceptCandidate();
  void decidePlacement(const KeyframeInput& keyframe, GraphBackend& backend);
  std::vector<LoopClosureInput> tryToPlace(const KeyframeInput& keyframe);
  std::vector<LoopClosureInput> placeByLocalizer(const KeyframeInput& keyframe,
                                                 const Eigen::Isometry3d& map_pose);
  /// The answer a keyframe at `map_pose` gives: tied to the saved keyframe nearest to it.
  std::optional<Answer> answerAt(const KeyframeInput& keyframe,
                                 const Eigen::Isometry3d& map_pose) const;
  std::vector<LoopClosureInput> confirmCandidate(const KeyframeInput& keyframe);
  /// Where two map poses of one keyframe agree within the placement tolerances (path: metres of
  /// odometry between the poses' evidence).
  bool samePlace(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double path) const;
  bool agree(const Answer& a, const Answer& b) const;
  LoopClosureInput tie(const Answer& answer) const;
  std::optional<LoopClosureInput> searchSavedMap(const KeyframeInput& keyframe,
                                                 const Eigen::Isometry3d& map_pose);

  MapResumeParams params_;
  std::shared_ptr<const Logger> logger_;
  std::shared_ptr<const MapPackage> package_;
  std::unique_ptr<Localizer> localizer_;
  std::unique_ptr<InterSessionLoopSearch> search_;
  std::vector<Answer> answers_;
  std::optional<Candidate> candidate_;
  /// map -> odom of the live session from its placement, until the back-end has applied it.
  Eigen::Isometry3d placed_map_to_odom_ = Eigen::Isometry3d::Identity();
  std::vector<LoopClosureInput> loops_;                ///< inter-session loops kept so far
  std::map<uint64_t, Eigen::Isometry3d> saved_poses_;  ///< saved keyframes after the replay
  std::map<uint64_t, Eigen::Isometry3d> loop_poses_;   ///< map poses their keyframes had
  std::map<uint64_t, double> loop_stamps_;
  MapResumeStatus status_;
  bool first_keyframe_ = true;
};

}  // namespace osm_graph_slam
