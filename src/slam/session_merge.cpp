#include "osm_graph_slam/slam/session_merge.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <set>

#include "osm_graph_slam/common/timing.h"
#include "osm_graph_slam/osm/enu_converter.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// A point of the `from` frame (ENU of one origin) in the `to` frame (ENU of another).
Eigen::Vector3d reproject(const EnuConverter& from, const EnuConverter& to,
                          const Eigen::Vector3d& enu) {
  const Eigen::Vector3d geo = from.toGeodetic(enu);
  return to.toEnu(geo.x(), geo.y(), geo.z());
}

/// Moves a dump's GNSS fixes and buildings from its own origin to the map's.
void moveToOrigin(GraphDump& dump, const EnuConverter& own, const EnuConverter& map) {
  for (auto& kf : dump.keyframes) {
    if (!kf.gnss_position) continue;
    const Eigen::Vector3d p =
        reproject(own, map,
                  Eigen::Vector3d(kf.gnss_position->x(), kf.gnss_position->y(),
                                  kf.gnss_altitude.value_or(0.0)));
    kf.gnss_position = p.head<2>();
    if (kf.gnss_altitude) kf.gnss_altitude = p.z();
  }
  for (auto& b : dump.buildings) map.project(b);
}

/// Renumbers a dump's keyframes (and everything that names them) as session `session`'s.
void mergeIds(GraphDump& dump, uint32_t session) {
  for (auto& kf : dump.keyframes) {
    kf.id = mergedKeyframeId(session, kf.id);
    kf.session = session;
  }
  std::map<uint64_t, std::vector<LineSegment2>> segments;
  for (auto& [id, segs] : dump.segments) segments[mergedKeyframeId(session, id)] = std::move(segs);
  dump.segments = std::move(segments);
  for (auto& l : dump.loops) {
    l.from_id = mergedKeyframeId(session, l.from_id);
    l.to_id = mergedKeyframeId(session, l.to_id);
  }
}

}  // namespace

SessionMerge::SessionMerge(const GraphBackendParams& backend, const LoopDetectorParams& loops,
                           const SessionMergeParams& params, std::shared_ptr<const Logger> logger)
    : backend_params_(backend),
      loop_params_(loops),
      params_(params),
      logger_(logger ? std::move(logger) : std::make_shared<Logger>()) {}

SessionMerge::~SessionMerge() = default;

bool SessionMerge::addSession(const std::string& name, GraphDump dump, std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = name + ": " + why;
    return false;
  };
  if (dump.keyframes.empty()) return fail("no keyframe");
  if (sessions_.size() >= static_cast<size_t>(GraphBackend::kMaxSessions) ||
      mergedKeyframeId(static_cast<uint32_t>(sessions_.size()), kSessionIdStride) >=
          static_cast<uint64_t>(GraphBackend::kKeyframeIdLimit))
    return fail("too many sessions for one graph (" + std::to_string(sessions_.size()) + ")");
  const auto largest =
      std::max_element(dump.keyframes.begin(), dump.keyframes.end(),
                       [](const KeyframeInput& a, const KeyframeInput& b) { return a.id < b.id; });
  if (largest->id >= kSessionIdStride)
    return fail("keyframe id " + std::to_string(largest->id) + " is beyond a session's " +
                std::to_string(kSessionIdStride) + " ids");
  if (!origin_ && dump.origin) origin_ = dump.origin;
  if (dump.origin && origin_ && *dump.origin != *origin_) {
    const EnuConverter own(dump.origin->x(), dump.origin->y(), dump.origin->z());
    const EnuConverter map(origin_->x(), origin_->y(), origin_->z());
    moveToOrigin(dump, own, map);
  } else if (!dump.origin && origin_) {
    return fail("no origin.txt: its GNSS fixes and buildings cannot be placed in the map");
  }
  dump.origin = origin_;
  mergeIds(dump, static_cast<uint32_t>(sessions_.size()));
  sessions_.push_back({name, std::move(dump)});
  return true;
}

SessionMergeReport SessionMerge::merge() {
  SessionMergeReport report;
  GraphBackendParams params = backend_params_;
  if (!sessions_.empty() && sessions_.front().dump.initial_heading) {
    params.initial_yaw_known = true;
    params.initial_yaw = *sessions_.front().dump.initial_heading;
  }
  backend_ = std::make_unique<GraphBackend>(params, logger_);

  // One dump of every session in turn: the buildings once (the first session's copy of a way),
  // each session's keyframes, segments and own loops.
  const auto t_add = Clock::now();
  GraphDump all;
  all.origin = origin_;
  std::set<std::pair<int64_t, int>> buildings;
  for (size_t i = 0; i < sessions_.size(); ++i) {
    const GraphDump& d = sessions_[i].dump;
    if (i > 0 && d.initial_heading)
      backend_->setSessionHeading(static_cast<uint32_t>(i), *d.initial_heading);
    for (const auto& b : d.buildings)
      if (buildings.insert({b.id, b.part}).second) all.buildings.push_back(b);
    all.keyframes.insert(all.keyframes.end(), d.keyframes.begin(), d.keyframes.end());
    all.segments.insert(d.segments.begin(), d.segments.end());
    all.loops.insert(all.loops.end(), d.loops.begin(), d.loops.end());
    SessionSummary summary;
    summary.name = sessions_[i].name;
    summary.session = static_cast<uint32_t>(i);
    summary.keyframes = d.keyframes.size();
    for (const auto& kf : d.keyframes) summary.keyframes_without_cloud += kf.cloud ? 0 : 1;
    report.sessions.push_back(summary);
    report.keyframes += d.keyframes.size();
  }
  const bool tiled = params_.tiles.tile_size > 0.0;
  report.last_update = replayGraphDump(all, *backend_, params_.optimize_every, !tiled);
  report.add_ms = msSince(t_add);

  if (params_.inter_session_loops && sessions_.size() > 1) {
    const auto t_loops = Clock::now();
    report.inter_session_loops = findInterSessionLoops(report);
    report.loops_ms = msSince(t_loops);
    for (const auto& l : report.inter_session_loops) backend_->addLoopClosure(l);
  }
  const auto t_opt = Clock::now();
  if (tiled)
    report.tiles = backend_->optimizeInTiles(params_.tiles);
  else if (!report.inter_session_loops.empty())
    report.last_update = backend_->update(true);
  report.optimize_ms = msSince(t_opt);
  if (params_.building_uncertainty) {
    const auto t_sigma = Clock::now();
    backend_->estimateBuildingUncertainty();
    report.uncertainty_ms = msSince(t_sigma);
  }
  report.buildings_by_sessions = buildingsBySessions();
  return report;
}

std::vector<LoopClosureInput> SessionMerge::findInterSessionLoops(SessionMergeReport& report) {
  InterSessionLoopSearch search(loop_params_, params_.loop_search, logger_);
  std::map<uint64_t, Eigen::Isometry3d> poses;
  for (const auto& [id, pose] : backend_->keyframeMapPoses()) poses[id] = pose;
  std::vector<LoopClosureInput> loops;
  for (size_t i = 0; i < sessions_.size(); ++i) {
    const auto& keyframes = sessions_[i].dump.keyframes;
    if (i > 0) {
      for (const auto& kf : keyframes) {
        if (!poses.count(kf.id)) continue;
        std::optional<LoopClosureInput> loop = search.query(kf.id, poses.at(kf.id), kf.cloud);
        if (!loop) continue;
        loops.push_back(*loop);
        ++report.sessions[i].inter_session_loops;
      }
    }
    for (const auto& kf : keyframes)
      if (poses.count(kf.id)) search.addToDatabase(kf.id, poses.at(kf.id), kf.cloud);
  }
  report.loop_queries = search.queries();
  std::map<uint64_t, double> stamps;
  for (const auto& session : sessions_)
    for (const auto& kf : session.dump.keyframes) stamps[kf.id] = kf.stamp;
  const std::vector<size_t> refused =
      inconsistentLoops(loops, poses, stamps, params_.loop_search, &SessionMerge::sessionOf);
  for (auto it = refused.rbegin(); it != refused.rend(); ++it) {
    --report.sessions[sessionOf(loops[*it].from_id)].inter_session_loops;
    loops.erase(loops.begin() + static_cast<std::ptrdiff_t>(*it));
  }
  report.loops_inconsistent = refused.size();
  logger_->info("inter-session loops: " + std::to_string(loops.size()) + " from " +
                std::to_string(report.loop_queries) + " keyframes searched (" +
                std::to_string(refused.size()) + " refused as inconsistent with their neighbours)");
  return loops;
}

std::map<size_t, size_t> SessionMerge::buildingsBySessions() const {
  std::map<int64_t, std::set<uint32_t>> seen_by;
  for (const auto& e : backend_->buildingObservations())
    seen_by[e.building].insert(sessionOf(e.keyframe));
  std::map<size_t, size_t> histogram;
  for (const auto& [building, sessions] : seen_by) ++histogram[sessions.size()];
  return histogram;
}

}  // namespace osm_graph_slam
