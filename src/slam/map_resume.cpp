#include "osm_graph_slam/slam/map_resume.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/common/timing.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/session_merge.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

/// The saved keyframe nearest to `position` (2-D): the one a placement is tied to.
const MapKeyframe* nearestKeyframe(const MapPackage& package, const Eigen::Vector3d& position) {
  const MapKeyframe* best = nullptr;
  double best_d = 0.0;
  for (const auto& kf : package.keyframes) {
    const double d = (kf.pose.translation() - position).head<2>().squaredNorm();
    if (!best || d < best_d) {
      best = &kf;
      best_d = d;
    }
  }
  return best;
}

}  // namespace

std::string MapResumeStatus::text() const {
  char line[320];
  if (placed_by_gnss)
    std::snprintf(line, sizeof(line),
                  "session %u placed by its GNSS fixes; %zu inter-session loops", session,
                  inter_session_loops);
  else if (placed_by_localizer)
    std::snprintf(line, sizeof(line),
                  "session %u handed over by the localiser at keyframe %llu (%.2f, %.2f, yaw "
                  "%.1f deg), %zu keyframes tied (%zu refused); %zu inter-session loops (%zu "
                  "refused as inconsistent)",
                  session, static_cast<unsigned long long>(placed_at.value_or(0)),
                  placement.translation().x(), placement.translation().y(),
                  planarPose(placement).theta * 180.0 / M_PI, localizer_ties,
                  localizer_ties_refused, inter_session_loops, loops_inconsistent);
  else if (placed)
    std::snprintf(line, sizeof(line),
                  "session %u placed at keyframe %llu (%.2f, %.2f, yaw %.1f deg) after %zu global "
                  "attempts (%zu answers); %zu inter-session loops (%zu refused as inconsistent)",
                  session, static_cast<unsigned long long>(placed_at.value_or(0)),
                  placement.translation().x(), placement.translation().y(),
                  planarPose(placement).theta * 180.0 / M_PI, global_attempts, global_answers,
                  inter_session_loops, loops_inconsistent);
  else
    std::snprintf(line, sizeof(line),
                  "session %u not placed on the saved map yet (%zu global attempts, %zu answers, "
                  "%zu disagreeing with odometry, %zu agreeing but unconfirmed): mapped on its own",
                  session, global_attempts, global_answers, answers_disagreeing,
                  placements_unconfirmed);
  return line;
}

MapResume::MapResume(const MapResumeParams& params, std::shared_ptr<const Logger> logger)
    : params_(params), logger_(logger ? std::move(logger) : std::make_shared<Logger>()) {}

MapResume::~MapResume() = default;

std::unique_ptr<MapResume> MapResume::load(const std::string& directory,
                                           const MapResumeParams& params,
                                           const LocalizationParams& localization,
                                           const LoopDetectorParams& loops, GraphBackend& backend,
                                           std::shared_ptr<const Logger> logger,
                                           std::string* error) {
  auto fail = [&](const std::string& why) -> std::unique_ptr<MapResume> {
    if (error) *error = "cannot resume on '" + directory + "': " + why;
    return nullptr;
  };
  if (backend.numKeyframes() > 0)
    return fail("the back-end already has keyframes (a map is resumed before the first one)");
  auto package = std::make_shared<MapPackage>();
  std::string why;
  if (!loadMapPackage(directory + "/map_package", *package, &why)) return fail(why);
  GraphDump dump;
  if (!readGraphDump(directory + "/graph", dump, &why))
    return fail("its graph (graph/, written by save_map) cannot be read: " + why);
  if (dump.keyframes.empty()) return fail("its graph has no keyframe");
  const size_t without_cloud = loadDumpClouds(directory + "/graph", dump, &why);
  uint32_t last_session = 0;
  for (auto& kf : dump.keyframes) {
    kf.session = SessionMerge::sessionOf(kf.id);
    last_session = std::max(last_session, kf.session);
  }
  if (last_session + 1 >= static_cast<uint32_t>(GraphBackend::kMaxSessions))
    return fail("it already holds the most sessions a graph can (" +
                std::to_string(GraphBackend::kMaxSessions) + ")");

  std::unique_ptr<MapResume> resume(new MapResume(params, std::move(logger)));
  MapResumeStatus& status = resume->status_;
  status.session = last_session + 1;
  status.saved_sessions = last_session + 1;
  status.saved_keyframes = dump.keyframes.size();
  const auto t0 = Clock::now();
  if (dump.initial_heading) backend.setInitialHeading(*dump.initial_heading);
  replayGraphDump(dump, backend, /*optimize_every=*/10);
  status.replay_ms = msSince(t0);

  resume->package_ = package;
  resume->localizer_ = std::make_unique<Localizer>(localization, package);
  resume->search_ =
      std::make_unique<InterSessionLoopSearch>(loops, params.loop_search, resume->logger_);
  std::map<uint64_t, PointCloudConstPtr> clouds;
  for (const auto& kf : dump.keyframes) clouds[kf.id] = kf.cloud;
  if (params.hold_saved_map) {
    std::map<uint64_t, Eigen::Isometry3d> saved;
    for (const auto& kf : package->keyframes) saved[kf.id] = kf.pose;
    backend.holdKeyframesAt(saved);
  }
  for (const auto& [id, pose] : backend.keyframeMapPoses()) {
    resume->saved_poses_[id] = pose;
    resume->search_->addToDatabase(id, pose, clouds[id]);
  }
  resume->logger_->info(
      "resumed on '" + directory + "': " + std::to_string(status.saved_keyframes) +
      " keyframes of " + std::to_string(status.saved_sessions) + " session(s) replayed in " +
      std::to_string(static_cast<int>(status.replay_ms)) + " ms" +
      (without_cloud ? " (" + std::to_string(without_cloud) + " without a cloud: " + why + ")"
                     : std::string()) +
      "; the live drive is session " + std::to_string(status.session));
  return resume;
}

uint64_t MapResume::graphId(uint64_t live_id) const {
  return mergedKeyframeId(status_.session, live_id);
}

void MapResume::renumber(KeyframeInput& keyframe) const {
  keyframe.id = graphId(keyframe.id);
  keyframe.session = status_.session;
}

void MapResume::decidePlacement(const KeyframeInput& keyframe, GraphBackend& backend) {
  first_keyframe_ = false;
  // A fix places the session only where the back-end uses fixes (GNSS priors); a GNSS-denied
  // run's first fix is a hint the localiser's answer replaces.
  if (keyframe.gnss_position && backend.params().gnss.gnss_prior_std > 0.0) {
    status_.placed = status_.placed_by_gnss = true;
    logger_->info(status_.text());
    return;
  }
  backend.setSessionUnplaced(status_.session);
  logger_->info("session " + std::to_string(status_.session) +
                " has no GNSS fix: not placed on the saved map until the global localiser "
                "places it; mapped on its own until then");
}

std::vector<LoopClosureInput> MapResume::process(
    const KeyframeInput& keyframe, GraphBackend& backend,
    const std::optional<Eigen::Isometry3d>& localized) {
  if (first_keyframe_) decidePlacement(keyframe, backend);
  if (localized) return placeByLocalizer(keyframe, *localized);
  if (!keyframe.cloud || keyframe.cloud->empty()) return {};
  if (!status_.placed) return candidate_ ? confirmCandidate(keyframe) : tryToPlace(keyframe);
  const Eigen::Isometry3d map_to_odom =
      backend.sessionPlaced(status_.session) ? backend.mapToOdom() : placed_map_to_odom_;
  std::optional<LoopClosureInput> loop = searchSavedMap(keyframe, map_to_odom * keyframe.odom_pose);
  if (!loop) return {};
  return {*loop};
}

std::vector<LoopClosureInput> MapResume::tryToPlace(const KeyframeInput& keyframe) {
  ++status_.global_attempts;
  const auto t0 = Clock::now();
  const GlobalLocalizationResult r = localizer_->globalLocalize(keyframe.cloud);
  status_.global_ms += msSince(t0);
  if (!r.success) return {};
  ++status_.global_answers;
  const std::optional<Answer> found = answerAt(keyframe, r.pose);
  if (!found) return {};
  const Answer& answer = *found;
  std::vector<Answer> agreeing;
  for (const auto& earlier : answers_)
    if (agree(answer, earlier)) agreeing.push_back(earlier);
  if (!answers_.empty() && agreeing.empty()) ++status_.answers_disagreeing;
  answers_.push_back(answer);
  if (static_cast<int>(answers_.size()) > std::max(1, params_.placement_memory))
    answers_.erase(answers_.begin());
  // Enough answers agree, and they are most of the recent ones: answers that keep landing on
  // different places (a self-similar street) are no placement, whichever two of them agree.
  const size_t votes = agreeing.size() + 1;
  if (static_cast<int>(votes) < std::max(1, params_.placement_answers) ||
      2 * votes <= answers_.size())
    return {};
  candidate_ = Candidate{{answer}, 0};
  candidate_->answers.insert(candidate_->answers.end(), agreeing.begin(), agreeing.end());
  return {};
}

std::optional<MapResume::Answer> MapResume::answerAt(const KeyframeInput& keyframe,
                                                     const Eigen::Isometry3d& map_pose) const {
  const MapKeyframe* saved = nearestKeyframe(*package_, map_pose.translation());
  if (!saved) return std::nullopt;
  return Answer{keyframe.id, keyframe.odom_pose, map_pose, keyframe.accum_distance, saved->id};
}

std::vector<LoopClosureInput> MapResume::placeByLocalizer(const KeyframeInput& keyframe,
                                                          const Eigen::Isometry3d& map_pose) {
  const std::optional<Answer> answer = answerAt(keyframe, map_pose);
  if (!answer) return {};
  // A tracked pose needs no vote: the localiser's filter already checked it scan by scan. The
  // later ties must still agree with the first through odometry (a localiser that slid along
  // a street on its way off the map would pull the session apart).
  if (status_.placed_by_localizer && !agree(*answer, answers_.front())) {
    ++status_.localizer_ties_refused;
    logger_->info("session " + std::to_string(status_.session) + ": the localiser's pose of " +
                  "keyframe " + std::to_string(keyframe.id) +
                  " disagrees with the first tie through odometry; not tied");
    return {};
  }
  if (!status_.placed) {
    status_.placed = status_.placed_by_localizer = true;
    status_.placed_at = keyframe.id;
    status_.placement = map_pose;
    placed_map_to_odom_ = map_pose * keyframe.odom_pose.inverse();
    answers_.assign(1, *answer);
    logger_->info(status_.text());
  }
  ++status_.localizer_ties;
  return {tie(*answer)};
}

std::vector<LoopClosureInput> MapResume::confirmCandidate(const KeyframeInput& keyframe) {
  Candidate& c = *candidate_;
  const Answer& newest = c.answers.front();
  const Eigen::Isometry3d map_to_odom = newest.map_pose * newest.odom_pose.inverse();
  const Eigen::Isometry3d predicted = map_to_odom * keyframe.odom_pose;
  ++c.keyframes;
  if (localizer_->distanceToMap(predicted.translation()) <= params_.placement_check_radius) {
    ++c.checks;
    const auto t0 = Clock::now();
    std::optional<LoopClosureInput> loop = search_->query(keyframe.id, predicted, keyframe.cloud);
    status_.loops_ms += msSince(t0);
    if (loop && saved_poses_.count(loop->to_id)) {
      const Eigen::Isometry3d said = saved_poses_.at(loop->to_id) * loop->relative_pose;
      if (!samePlace(said, predicted, std::abs(keyframe.accum_distance - newest.accum_distance))) {
        logger_->info("session " + std::to_string(status_.session) + ": the loop " +
                      std::to_string(keyframe.id) + " -> " + std::to_string(loop->to_id) +
                      " puts its keyframe " +
                      std::to_string((said.translation() - predicted.translation()).norm()) +
                      " m from where the placement does");
        c.checks = -1;  // a verified loop elsewhere: the candidate is wrong
      } else {
        c.loops.push_back(*loop);
        c.loop_poses.emplace_back(keyframe.id, predicted);
        c.loop_stamps.push_back(keyframe.stamp);
      }
    }
  }
  const std::optional<bool> verdict = candidateVerdict(c);
  if (!verdict) return {};
  if (*verdict) return acceptCandidate();
  ++status_.placements_unconfirmed;
  logger_->info("session " + std::to_string(status_.session) + ": a placement at (" +
                std::to_string(newest.map_pose.translation().x()) + ", " +
                std::to_string(newest.map_pose.translation().y()) +
                ") was not confirmed by inter-session loops (" + std::to_string(c.loops.size()) +
                " of " + std::to_string(std::max(c.checks, 0)) +
                " keyframes on the map); searching again");
  candidate_.reset();
  return {};
}

std::optional<bool> MapResume::candidateVerdict(const Candidate& c) const {
  if (c.checks < 0) return false;
  if (c.checks >= std::max(1, params_.placement_checks))
    return static_cast<double>(c.loops.size()) >= params_.placement_confirm_fraction * c.checks;
  if (c.keyframes >= std::max(1, params_.placement_check_patience)) return false;
  return std::nullopt;
}

std::vector<LoopClosureInput> MapResume::acceptCandidate() {
  Candidate& c = *candidate_;
  const Answer& newest = c.answers.front();
  status_.placed = true;
  status_.placed_at = newest.keyframe;
  status_.placement = newest.map_pose;
  placed_map_to_odom_ = newest.map_pose * newest.odom_pose.inverse();
  std::vector<LoopClosureInput> loops;
  for (const auto& a : c.answers) loops.push_back(tie(a));
  for (size_t i = 0; i < c.loops.size(); ++i) {
    loops_.push_back(c.loops[i]);
    loop_poses_[c.loop_poses[i].first] = c.loop_poses[i].second;
    loop_poses_[c.loops[i].to_id] = saved_poses_.at(c.loops[i].to_id);
    loop_stamps_[c.loop_poses[i].first] = c.loop_stamps[i];
    loops.push_back(c.loops[i]);
  }
  status_.inter_session_loops += c.loops.size();
  candidate_.reset();
  logger_->info(status_.text());
  return loops;
}

bool MapResume::samePlace(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                          double path) const {
  const double tolerance =
      params_.placement_tolerance + params_.placement_tolerance_per_meter * path;
  return (a.translation() - b.translation()).norm() <= tolerance &&
         std::abs(planarPose(a.inverse() * b).theta) <= params_.placement_tolerance_yaw;
}

bool MapResume::agree(const Answer& a, const Answer& b) const {
  // b's answer carried to a by odometry against a's own answer.
  return samePlace(b.map_pose * b.odom_pose.inverse() * a.odom_pose, a.map_pose,
                   std::abs(a.accum_distance - b.accum_distance));
}

LoopClosureInput MapResume::tie(const Answer& answer) const {
  // The loop edge to -> from: the live keyframe in the saved one's frame, as the localiser
  // registered it against the saved map.
  const auto saved =
      std::find_if(package_->keyframes.begin(), package_->keyframes.end(),
                   [&](const MapKeyframe& kf) { return kf.id == answer.saved_keyframe; });
  LoopClosureInput loop;
  loop.from_id = answer.keyframe;
  loop.to_id = answer.saved_keyframe;
  loop.relative_pose = saved->pose.inverse() * answer.map_pose;
  const double xy = 1.0 / (params_.placement_std_xy * params_.placement_std_xy);
  const double angle = 1.0 / (params_.placement_std_yaw * params_.placement_std_yaw);
  loop.information.setZero();
  loop.information.diagonal() << xy, xy, xy, angle, angle, angle;
  return loop;
}

std::optional<LoopClosureInput> MapResume::searchSavedMap(const KeyframeInput& keyframe,
                                                          const Eigen::Isometry3d& map_pose) {
  const auto t0 = Clock::now();
  std::optional<LoopClosureInput> loop = search_->query(keyframe.id, map_pose, keyframe.cloud);
  status_.loops_ms += msSince(t0);
  if (!loop || !saved_poses_.count(loop->to_id)) return std::nullopt;
  loops_.push_back(*loop);
  loop_poses_[keyframe.id] = map_pose;
  loop_poses_[loop->to_id] = saved_poses_.at(loop->to_id);
  loop_stamps_[keyframe.id] = keyframe.stamp;
  const std::vector<size_t> refused = inconsistentLoops(
      loops_, loop_poses_, loop_stamps_, params_.loop_search, &SessionMerge::sessionOf);
  if (std::find(refused.begin(), refused.end(), loops_.size() - 1) != refused.end()) {
    loops_.pop_back();
    ++status_.loops_inconsistent;
    return std::nullopt;
  }
  ++status_.inter_session_loops;
  return loop;
}

}  // namespace osm_graph_slam
