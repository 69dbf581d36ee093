#include "osm_graph_slam/loop/loop_detector.h"

#include <pcl/filters/voxel_grid.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <list>
#include <nanoflann.hpp>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "osm_graph_slam/cloud/voxel_filter.h"
#include "osm_graph_slam/common/dynamic_kd_index.h"
#include "osm_graph_slam/loop/landmark_loop_source.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double yawOf(const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d x = pose.linear().col(0);
  return std::atan2(x.y(), x.x());
}

double wrapPi(double a) {
  return std::atan2(std::sin(a), std::cos(a));
}

Eigen::Isometry3d planarIsometry(double x, double y, double z, double yaw) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).matrix();
  pose.translation() = Eigen::Vector3d(x, y, z);
  return pose;
}

}  // namespace

PointCloudPtr downsampleForLoop(const PointCloud& cloud, double leaf, bool use_pcl) {
  if (leaf > 0.0 && !use_pcl) return voxelCentroids(cloud, leaf);
  auto finite = std::make_shared<PointCloud>();
  finite->reserve(cloud.size());
  for (const auto& p : cloud.points) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) finite->push_back(p);
  }
  if (leaf <= 0.0 || finite->empty()) return finite;
  pcl::VoxelGrid<PointT> grid;
  grid.setLeafSize(leaf, leaf, leaf);
  grid.setInputCloud(finite);
  auto out = std::make_shared<PointCloud>();
  grid.filter(*out);
  return out;
}

namespace {

/// nanoflann view of a PCL cloud (x, y, z of PointT).
struct CloudAdaptor {
  const PointCloud* cloud = nullptr;
  size_t kdtree_get_point_count() const { return cloud->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return cloud->points[i].data[dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using CloudKdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>,
                                        CloudAdaptor, 3, uint32_t>;

}  // namespace

double overlapRatio(const PointCloud& source, const PointCloud& target,
                    const Eigen::Isometry3d& transform, double max_distance) {
  if (source.empty() || target.empty()) return 0.0;
  // nanoflann: measured ~3x faster than pcl::KdTreeFLANN here (build + one query per point).
  CloudAdaptor adaptor{&target};
  CloudKdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  const Eigen::Affine3f t = transform.cast<float>();
  const float max_sq = static_cast<float>(max_distance * max_distance);
  size_t inliers = 0;
  for (const auto& p : source.points) {
    const Eigen::Vector3f q = t * p.getVector3fMap();
    uint32_t index = 0;
    float dist_sq = 0.f;
    if (tree.knnSearch(q.data(), 1, &index, &dist_sq) == 1 && dist_sq <= max_sq) ++inliers;
  }
  return static_cast<double>(inliers) / static_cast<double>(source.size());
}

/// The cloud kept for verification: downsampled, or (voxel_size <= 0) the caller's cloud itself
/// when it is all finite, so already filtered keyframe clouds are not copied.
static PointCloudConstPtr storedCloud(const PointCloudConstPtr& cloud, double voxel_size,
                                      bool use_pcl) {
  if (voxel_size <= 0.0) {
    const bool finite = std::all_of(cloud->begin(), cloud->end(), [](const PointT& p) {
      return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    });
    if (finite) return cloud;
  }
  return downsampleForLoop(*cloud, voxel_size, use_pcl);
}

/// Everything computed once per keyframe: descriptor and the two registration clouds.
struct LoopDetector::Query {
  uint64_t id = 0;
  ScanContext descriptor;
  PointCloudConstPtr cloud;
  PointCloudConstPtr coarse_cloud;
  PointCloudConstPtr fine_cloud;            ///< fine-stage source (fine_query_voxel_size)
  std::vector<Eigen::Vector2f> bev_points;  ///< correlative stage
  bool usable = false;
  std::string problem;
};

/// Likelihood fields of recently verified candidates (LRU by database index): a revisit verifies
/// the same few keyframes for several consecutive queries.
struct LoopDetector::FieldCache {
  std::list<std::pair<size_t, BevLikelihoodField>> items;  ///< most recent first
  std::unordered_map<size_t, std::list<std::pair<size_t, BevLikelihoodField>>::iterator> where;
};

LoopDetector::LoopDetector(const LoopDetectorParams& params, LogSink log_sink)
    : params_(params),
      logger_(log_sink),
      ring_key_index_(std::make_unique<DynamicKdIndex>(params.scan_context.num_rings)),
      position_index_(std::make_unique<DynamicKdIndex>(3)),
      field_cache_(std::make_unique<FieldCache>()),
      clouds_(std::make_shared<CloudStore>(params.cloud_store, log_sink)) {
  if (params_.method != "scan_context" && params_.method != "geometric_hierarchy" &&
      params_.method != "combined") {
    throw std::invalid_argument("loop detection: unknown method '" + params_.method +
                                "' (scan_context | geometric_hierarchy | combined)");
  }
  if (params_.method != "scan_context") {
    landmark_source_ =
        std::make_unique<LandmarkLoopSource>(params_.landmark_extraction, params_.landmarks);
  }
  if (params_.voxel_filter != "own" && params_.voxel_filter != "pcl") {
    throw std::invalid_argument("loop detection: unknown voxel_filter '" + params_.voxel_filter +
                                "' (own | pcl)");
  }
  if (params_.coarse_method != "correlative" && params_.coarse_method != "gicp") {
    throw std::invalid_argument("loop detection: unknown coarse_method '" + params_.coarse_method +
                                "' (correlative | gicp)");
  }
  // The BEV stage separates ground from structure exactly like the descriptor does.
  params_.correlative.sensor_height = params_.scan_context.sensor_height;
  params_.correlative.min_height = params_.scan_context.min_height;
  params_.correlative.max_height = params_.scan_context.max_height;
  RegistrationParams fine = params_.registration;
  fine.target_cache_size = std::max(1, params_.candidate_cache_size);
  fine.max_source_points = std::max(0, params_.fine_max_source_points);
  fine_registration_ = createRegistration(fine);
  if (params_.coarse_max_correspondence_distance > 0.0) {
    RegistrationParams coarse = params_.registration;
    coarse.max_correspondence_distance = params_.coarse_max_correspondence_distance;
    coarse_registration_ = createRegistration(coarse);
  }
}

LoopDetector::~LoopDetector() = default;

size_t LoopDetector::indexLimitForDistance(double accum_distance) const {
  // Keyframes arrive in trajectory order, so accumulated distances are non-decreasing.
  const double limit = accum_distance - params_.min_accum_distance_gap;
  auto it = std::upper_bound(
      entries_.begin(), entries_.end(), limit,
      [](double value, const LoopDatabaseEntry& e) { return value < e.accum_distance; });
  return static_cast<size_t>(it - entries_.begin());
}

std::vector<size_t> LoopDetector::odometryCandidates(const Eigen::Isometry3d& odom_pose,
                                                     double accum_distance) const {
  const size_t limit = indexLimitForDistance(accum_distance);
  if (limit == 0) return {};
  const Eigen::Vector3f position = odom_pose.translation().cast<float>();
  const auto near = position_index_->radius(position.data(),
                                            static_cast<float>(params_.search_radius_max), limit);
  std::vector<size_t> out;
  out.reserve(near.size());
  for (const auto& [index, dist_sq] : near) {
    const double gap = accum_distance - entries_[index].accum_distance;
    const double radius =
        std::min(params_.search_radius_max,
                 params_.search_radius_base + params_.search_radius_per_meter * std::max(0.0, gap));
    if (dist_sq <= radius * radius) out.push_back(index);
  }
  return out;
}

std::vector<size_t> LoopDetector::ringKeyCandidates(const ScanContext& query,
                                                    size_t index_limit) const {
  const auto nearest = ring_key_index_->knn(
      query.ring_key.data(), static_cast<size_t>(std::max(1, params_.ring_key_candidates)),
      index_limit);
  std::vector<size_t> out;
  out.reserve(nearest.size());
  for (const auto& item : nearest) out.push_back(item.first);
  return out;
}

std::vector<RankedCandidate> LoopDetector::rankCandidates(const ScanContext& query,
                                                          std::vector<size_t> indices) const {
  const size_t keep_ring = static_cast<size_t>(std::max(1, params_.ring_key_candidates));
  if (indices.size() > keep_ring) {
    std::vector<std::pair<float, size_t>> by_ring;
    by_ring.reserve(indices.size());
    for (size_t index : indices) {
      by_ring.push_back(
          {(entries_[index].descriptor.ring_key - query.ring_key).squaredNorm(), index});
    }
    std::nth_element(by_ring.begin(), by_ring.begin() + keep_ring, by_ring.end());
    indices.clear();
    for (size_t i = 0; i < keep_ring; ++i) indices.push_back(by_ring[i].second);
  }
  std::vector<RankedCandidate> ranked;
  for (size_t index : indices) {
    RankedCandidate c;
    c.index = index;
    c.match = matchScanContexts(query, entries_[index].descriptor, params_.scan_context);
    if (c.match.distance <= params_.max_descriptor_distance) ranked.push_back(c);
  }
  std::sort(ranked.begin(), ranked.end(),
            [](const auto& a, const auto& b) { return a.match.distance < b.match.distance; });
  const size_t k = static_cast<size_t>(std::max(1, params_.num_candidates));
  if (ranked.size() > k) ranked.resize(k);
  return ranked;
}

void LoopDetector::addOdometryNearest(const ScanContext& query, size_t nearest,
                                      std::vector<RankedCandidate>& ranked) const {
  // Verified first: on a revisit it is the likeliest true match and the one with the most
  // overlap, so verification usually stops after it (stop_at_first_accepted).
  auto found = std::find_if(ranked.begin(), ranked.end(),
                            [&](const RankedCandidate& c) { return c.index == nearest; });
  if (found != ranked.end()) {
    std::rotate(ranked.begin(), found, found + 1);
    return;
  }
  RankedCandidate c;
  c.index = nearest;
  c.match = matchScanContexts(query, entries_[nearest].descriptor, params_.scan_context);
  if (c.match.distance <= params_.max_descriptor_distance) ranked.insert(ranked.begin(), c);
}

Matrix6d LoopDetector::informationFromFitness(double fitness) const {
  const double rms = std::sqrt(std::max(0.0, fitness));
  const double st = std::clamp(params_.translation_stddev_per_rms * rms,
                               params_.min_translation_stddev, params_.max_translation_stddev);
  const double sr = std::clamp(params_.rotation_stddev_per_rms * rms, params_.min_rotation_stddev,
                               params_.max_rotation_stddev);
  Matrix6d info = Matrix6d::Zero();
  info.diagonal() << 1.0 / (st * st), 1.0 / (st * st), 1.0 / (st * st), 1.0 / (sr * sr),
      1.0 / (sr * sr), 1.0 / (sr * sr);
  return info;
}

bool LoopDetector::consistentWithOdometry(const LoopDatabaseEntry& target,
                                          const Eigen::Isometry3d& transform,
                                          const Eigen::Isometry3d& odom_pose,
                                          double accum_distance) const {
  const Eigen::Isometry3d odom_relative = target.odom_pose.inverse() * odom_pose;
  const double gap = std::max(0.0, accum_distance - target.accum_distance);
  const double dt = (odom_relative.translation() - transform.translation()).norm();
  const double dyaw = std::abs(wrapPi(yawOf(odom_relative) - yawOf(transform)));
  const double t_tol = params_.odometry_translation_tolerance_base +
                       params_.odometry_translation_tolerance_per_meter * gap;
  const double yaw_tol =
      params_.odometry_yaw_tolerance_base + params_.odometry_yaw_tolerance_per_meter * gap;
  return dt <= t_tol && dyaw <= yaw_tol;
}

std::optional<DetectedLoop> LoopDetector::rejectCandidate(CandidateOutcome& outcome,
                                                          const char* verdict, int& counter) {
  ++counter;
  outcome.verdict = verdict;
  stats_.outcomes.push_back(outcome);
  return std::nullopt;
}

bool LoopDetector::useCorrelative(const std::optional<Eigen::Isometry3d>& odom_pose) const {
  return odom_pose.has_value() && params_.coarse_method == "correlative";
}

const BevLikelihoodField& LoopDetector::fieldOf(size_t index) {
  FieldCache& cache = *field_cache_;
  auto found = cache.where.find(index);
  if (found != cache.where.end()) {
    cache.items.splice(cache.items.begin(), cache.items, found->second);
    return cache.items.front().second;
  }
  cache.items.emplace_front(index,
                            BevLikelihoodField(*entryCloud(index, false), params_.correlative));
  cache.where[index] = cache.items.begin();
  while (cache.items.size() > static_cast<size_t>(std::max(1, params_.field_cache_size))) {
    cache.where.erase(cache.items.back().first);
    cache.items.pop_back();
  }
  return cache.items.front().second;
}

PointCloudConstPtr LoopDetector::entryCloud(size_t index, bool coarse) {
  const uint64_t key = 2 * index + (coarse ? 1 : 0);
  for (auto it = decoded_.begin(); it != decoded_.end(); ++it) {
    if (it->first != key) continue;
    decoded_.splice(decoded_.begin(), decoded_, it);
    return it->second;
  }
  const LoopDatabaseEntry& entry = entries_[index];
  std::string error;
  PointCloudConstPtr cloud = (coarse ? entry.coarse_cloud : entry.cloud).load(&error);
  if (!cloud) {
    // An unreadable spilled cloud fails its candidate's registration, not the search.
    logger_.warnOnce("loop_store_read",
                     "loop detection: " + error + "; its candidates are rejected (reported once)");
    cloud = std::make_shared<PointCloud>();
  }
  decoded_.emplace_front(key, cloud);
  const size_t keep = 2 * static_cast<size_t>(std::max(4, params_.candidate_cache_size));
  while (decoded_.size() > keep) decoded_.pop_back();
  return cloud;
}

std::optional<DetectedLoop> LoopDetector::verifyCorrelative(const Query& query,
                                                            const RankedCandidate& candidate,
                                                            const Eigen::Isometry3d& odom_pose,
                                                            double accum_distance) {
  const LoopDatabaseEntry& target = entries_[candidate.index];
  ++stats_.verified;
  CandidateOutcome outcome;
  outcome.id = target.id;
  if (candidate.landmark_guess) outcome.source = "geometric_hierarchy";
  outcome.descriptor_distance = candidate.match.distance;
  // The window is every pose the odometry check could accept: the best pose in it is the one
  // the evidence prefers, and a second placement in it that fits as well makes the match
  // ambiguous whatever the fine stage would settle on.
  const Eigen::Isometry3d odom_relative = target.odom_pose.inverse() * odom_pose;
  const double gap = std::max(0.0, accum_distance - target.accum_distance);
  BevSearchWindow window;
  window.center = Eigen::Vector3d(odom_relative.translation().x(), odom_relative.translation().y(),
                                  yawOf(odom_relative));
  window.translation_radius = params_.odometry_translation_tolerance_base +
                              params_.odometry_translation_tolerance_per_meter * gap;
  window.yaw_radius =
      params_.odometry_yaw_tolerance_base + params_.odometry_yaw_tolerance_per_meter * gap;
  auto start = Clock::now();
  const BevSearchResult bev =
      searchBev(fieldOf(candidate.index), query.bev_points, window, params_.correlative);
  stats_.correlative_ms += msSince(start);
  outcome.bev_score = bev.best_score;
  outcome.ambiguity = bev.ambiguity();
  outcome.transform =
      planarIsometry(bev.best.x(), bev.best.y(), odom_relative.translation().z(), bev.best.z());
  if (!bev.valid) return rejectCandidate(outcome, "correlative", stats_.rejected_coarse);
  if (bev.ambiguity() >= params_.max_ambiguity) {
    return rejectCandidate(outcome, "ambiguous", stats_.rejected_ambiguous);
  }
  return fineStage(query, candidate, outcome.transform, odom_pose, accum_distance, outcome,
                   &bev.best);
}

std::optional<DetectedLoop> LoopDetector::verifyCandidate(
    const Query& query, const RankedCandidate& candidate, Eigen::Isometry3d guess,
    const std::optional<Eigen::Isometry3d>& odom_pose, double accum_distance) {
  const LoopDatabaseEntry& target = entries_[candidate.index];
  const bool check_odometry = odom_pose && params_.check_odometry_consistency;
  ++stats_.verified;
  CandidateOutcome outcome;
  outcome.id = target.id;
  if (candidate.landmark_guess) outcome.source = "geometric_hierarchy";
  outcome.descriptor_distance = candidate.match.distance;
  if (coarse_registration_) {
    auto start = Clock::now();
    coarse_registration_->setTarget(entryCloud(candidate.index, true));  // kept when repeated
    const RegistrationResult coarse = coarse_registration_->align(query.coarse_cloud, guess);
    stats_.coarse_ms += msSince(start);
    outcome.coarse_fitness = coarse.fitness;
    outcome.transform = coarse.transform;
    // Early rejects: the fine stage moves the result by well under a metre, so a coarse result
    // that fits badly or contradicts odometry cannot become an accepted loop.
    if (params_.coarse_max_fitness > 0.0 &&
        (!coarse.converged || !(coarse.fitness <= params_.coarse_max_fitness))) {
      return rejectCandidate(outcome, "coarse_fitness", stats_.rejected_coarse);
    }
    if (check_odometry &&
        !consistentWithOdometry(target, coarse.transform, *odom_pose, accum_distance)) {
      return rejectCandidate(outcome, "coarse_odometry", stats_.rejected_coarse);
    }
    if (coarse.converged) guess = coarse.transform;
  }
  return fineStage(query, candidate, guess, odom_pose, accum_distance, outcome, nullptr);
}

std::optional<DetectedLoop> LoopDetector::fineStage(
    const Query& query, const RankedCandidate& candidate, const Eigen::Isometry3d& guess,
    const std::optional<Eigen::Isometry3d>& odom_pose, double accum_distance,
    CandidateOutcome& outcome, const Eigen::Vector3d* correlative_peak) {
  const LoopDatabaseEntry& target = entries_[candidate.index];
  const bool check_odometry = odom_pose && params_.check_odometry_consistency;
  auto start = Clock::now();
  ++stats_.fine_registrations;
  const PointCloudConstPtr target_cloud = entryCloud(candidate.index, false);
  fine_registration_->setTarget(target_cloud);
  stats_.fine_target_ms += msSince(start);
  const RegistrationResult fine = fine_registration_->align(query.fine_cloud, guess);
  stats_.fine_ms += msSince(start);
  stats_.fine_iterations += fine.iterations;
  outcome.fitness = fine.fitness;
  outcome.transform = fine.transform;
  if (!fine.converged || !(fine.fitness <= params_.max_fitness)) {
    return rejectCandidate(outcome, "fitness", stats_.rejected_fitness);
  }
  if (correlative_peak &&
      (fine.transform.translation().head<2>() - correlative_peak->head<2>()).norm() >
          params_.max_refinement_shift) {
    return rejectCandidate(outcome, "refinement", stats_.rejected_refinement);
  }
  start = Clock::now();
  // The fine stage already indexed the target: measure the overlap on its tree.
  const std::optional<double> overlap =
      fine_registration_->overlap(*query.cloud, fine.transform, params_.overlap_distance);
  outcome.overlap =
      overlap ? *overlap
              : overlapRatio(*query.cloud, *target_cloud, fine.transform, params_.overlap_distance);
  stats_.overlap_ms += msSince(start);
  if (outcome.overlap < params_.min_overlap) {
    return rejectCandidate(outcome, "overlap", stats_.rejected_overlap);
  }
  if (check_odometry &&
      !consistentWithOdometry(target, fine.transform, *odom_pose, accum_distance)) {
    return rejectCandidate(outcome, "odometry", stats_.rejected_odometry);
  }
  outcome.verdict = "accepted";
  stats_.outcomes.push_back(outcome);
  DetectedLoop loop;
  loop.from_id = query.id;
  loop.to_id = target.id;
  loop.relative_pose = fine.transform;
  loop.information = informationFromFitness(fine.fitness);
  loop.descriptor_distance = candidate.match.distance;
  loop.descriptor_yaw = candidate.match.yaw;
  loop.fitness = fine.fitness;
  loop.overlap = outcome.overlap;
  return loop;
}

std::vector<Eigen::Isometry3d> LoopDetector::seedsFor(
    const RankedCandidate& candidate, const std::optional<Eigen::Isometry3d>& odom_pose) const {
  if (candidate.landmark_guess) return {*candidate.landmark_guess};
  const LoopDatabaseEntry& target = entries_[candidate.index];
  // Rotation from the descriptor. Translation: first from odometry when there is one (so that
  // on repetitive facades registration settles in the alias nearest to the odometry), then,
  // if that fails, zero (revisits in the other lane are closer to zero than drifted odometry).
  std::vector<Eigen::Isometry3d> seeds;
  Eigen::Isometry3d seed = Eigen::Isometry3d::Identity();
  seed.linear() = Eigen::AngleAxisd(candidate.match.yaw, Eigen::Vector3d::UnitZ()).matrix();
  if (odom_pose && params_.seed_translation_from_odometry) {
    Eigen::Isometry3d from_odometry = seed;
    from_odometry.translation() = (target.odom_pose.inverse() * (*odom_pose)).translation();
    seeds.push_back(from_odometry);
    if (params_.retry_zero_translation_seed) seeds.push_back(seed);
  } else {
    seeds.push_back(seed);
  }
  return seeds;
}

std::optional<DetectedLoop> LoopDetector::verify(const Query& query,
                                                 const std::vector<RankedCandidate>& ranked,
                                                 const std::optional<Eigen::Isometry3d>& odom_pose,
                                                 double accum_distance) {
  std::optional<DetectedLoop> best;
  for (const auto& candidate : ranked) {
    std::optional<DetectedLoop> loop;
    if (candidate.landmark_guess && odom_pose && params_.check_odometry_consistency &&
        !consistentWithOdometry(entries_[candidate.index], *candidate.landmark_guess, *odom_pose,
                                accum_distance)) {
      // The landmark transform is the proposal's own evidence: if odometry rules it out, no
      // registration is spent on it.
      CandidateOutcome outcome;
      outcome.id = entries_[candidate.index].id;
      outcome.source = "geometric_hierarchy";
      outcome.transform = *candidate.landmark_guess;
      rejectCandidate(outcome, "landmark_odometry", stats_.rejected_coarse);
    } else if (useCorrelative(odom_pose)) {
      // One search covers every seed the odometry check could accept.
      loop = verifyCorrelative(query, candidate, *odom_pose, accum_distance);
    } else {
      for (const auto& guess : seedsFor(candidate, odom_pose)) {
        loop = verifyCandidate(query, candidate, guess, odom_pose, accum_distance);
        if (loop) break;
      }
    }
    if (loop && candidate.landmark_guess) {
      loop->source = "geometric_hierarchy";
      loop->landmark_inliers = candidate.landmark_inliers;
    }
    if (loop && (!best || loop->fitness < best->fitness)) best = loop;
    if (best && params_.stop_at_first_accepted) break;
  }
  return best;
}

void LoopDetector::addLandmarkCandidate(const Query& query, const PointCloudConstPtr& cloud,
                                        size_t index_limit,
                                        const std::optional<Eigen::Isometry3d>& odom_pose,
                                        std::vector<RankedCandidate>& ranked) {
  const auto proposal = landmark_source_->propose(cloud, index_limit);
  const LandmarkSourceStats& ls = landmark_source_->lastStats();
  stats_.landmark_extraction_ms = ls.extraction_ms;
  stats_.landmark_query_ms = ls.query_ms;
  stats_.landmarks = ls.landmarks;
  stats_.landmark_proposal = proposal.has_value();
  if (!proposal) return;
  for (const auto& c : ranked)
    if (c.index == proposal->index) return;  // Scan Context's candidate is verified already
  RankedCandidate c;
  c.index = proposal->index;
  if (useScanContext()) {
    c.match =
        matchScanContexts(query.descriptor, entries_[c.index].descriptor, params_.scan_context);
  }
  c.landmark_guess = proposal->relative_pose;
  // Landmarks are planar: the height difference (terrain) comes from odometry when there is one.
  if (odom_pose) {
    c.landmark_guess->translation().z() =
        (entries_[c.index].odom_pose.inverse() * (*odom_pose)).translation().z();
  }
  c.landmark_inliers = proposal->inliers;
  ranked.push_back(c);
}

std::optional<DetectedLoop> LoopDetector::detect(const LoopKeyframe& keyframe) {
  stats_ = LoopQueryStats();
  auto start = Clock::now();
  Query query;
  query.id = keyframe.id;
  last_query_ = LastQuery();
  if (!keyframe.cloud || keyframe.cloud->empty()) {
    stats_.reason = "keyframe " + std::to_string(keyframe.id) + " has no points";
    return std::nullopt;
  }
  last_query_.input = keyframe.cloud;
  if (useScanContext()) {
    query.descriptor = computeScanContext(*keyframe.cloud, params_.scan_context);
    last_query_.descriptor = query.descriptor;
  }
  stats_.descriptor_ms = msSince(start);

  start = Clock::now();
  std::vector<size_t> candidates = odometryCandidates(keyframe.odom_pose, keyframe.accum_distance);
  stats_.phase1_candidates = static_cast<int>(candidates.size());
  stats_.candidates_ms = msSince(start);
  if (candidates.empty()) {
    stats_.reason = "no odometry candidates";
    return std::nullopt;
  }
  start = Clock::now();
  std::vector<RankedCandidate> ranked;
  if (useScanContext()) {
    const size_t nearest = candidates.front();  // phase 1 returns the closest first
    ranked = rankCandidates(query.descriptor, std::move(candidates));
    if (params_.verify_odometry_nearest) addOdometryNearest(query.descriptor, nearest, ranked);
  }
  stats_.ranking_ms = msSince(start);
  // The hierarchy searches every keyframe far enough back, not only phase 1's: its proposal
  // carries a transform that the odometry check tests before any registration.
  if (landmark_source_) {
    addLandmarkCandidate(query, keyframe.cloud, indexLimitForDistance(keyframe.accum_distance),
                         keyframe.odom_pose, ranked);
  }
  stats_.phase2_candidates = static_cast<int>(ranked.size());
  if (ranked.empty()) {
    stats_.reason = "no candidate within the descriptor distance";
    return std::nullopt;
  }
  return prepareAndVerify(query, ranked, keyframe.cloud, keyframe.odom_pose,
                          keyframe.accum_distance);
}

std::optional<DetectedLoop> LoopDetector::relocalize(const LoopKeyframe& keyframe) {
  stats_ = LoopQueryStats();
  last_query_ = LastQuery();
  if (!keyframe.cloud || keyframe.cloud->empty()) {
    stats_.reason = "relocalisation cloud has no points";
    return std::nullopt;
  }
  auto start = Clock::now();
  Query query;
  query.id = keyframe.id;
  last_query_.input = keyframe.cloud;
  if (useScanContext()) {
    query.descriptor = computeScanContext(*keyframe.cloud, params_.scan_context);
    last_query_.descriptor = query.descriptor;
  }
  stats_.descriptor_ms = msSince(start);
  const size_t limit = keyframe.accum_distance < 0.0
                           ? entries_.size()
                           : indexLimitForDistance(keyframe.accum_distance);
  std::vector<RankedCandidate> ranked;
  if (useScanContext()) {
    start = Clock::now();
    auto candidates = ringKeyCandidates(query.descriptor, limit);
    stats_.phase1_candidates = static_cast<int>(candidates.size());
    stats_.candidates_ms = msSince(start);
    start = Clock::now();
    ranked = rankCandidates(query.descriptor, std::move(candidates));
    stats_.ranking_ms = msSince(start);
  }
  if (landmark_source_) addLandmarkCandidate(query, keyframe.cloud, limit, std::nullopt, ranked);
  stats_.phase2_candidates = static_cast<int>(ranked.size());
  if (ranked.empty()) {
    stats_.reason = "no keyframe within the descriptor distance";
    return std::nullopt;
  }
  return prepareAndVerify(query, ranked, keyframe.cloud, std::nullopt, 0.0);
}

std::optional<DetectedLoop> LoopDetector::prepareAndVerify(
    Query& query, const std::vector<RankedCandidate>& ranked, const PointCloudConstPtr& cloud,
    const std::optional<Eigen::Isometry3d>& odom_pose, double accum_distance) {
  const auto start = Clock::now();
  query.cloud = storedCloud(cloud, params_.voxel_size, pclVoxelFilter());
  if (cloud == last_query_.input) last_query_.stored = query.cloud;
  query.fine_cloud =
      params_.fine_query_voxel_size > params_.voxel_size
          ? downsampleForLoop(*query.cloud, params_.fine_query_voxel_size, pclVoxelFilter())
          : query.cloud;
  if (useCorrelative(odom_pose)) {
    query.bev_points = bevQueryPoints(*query.cloud, params_.correlative);
  } else {
    query.coarse_cloud =
        coarse_registration_
            ? downsampleForLoop(*query.cloud, params_.coarse_voxel_size, pclVoxelFilter())
            : query.cloud;
  }
  stats_.prepare_ms = msSince(start);
  auto loop = verify(query, ranked, odom_pose, accum_distance);
  stats_.verification_ms = msSince(start);
  stats_.accepted = loop.has_value();
  if (!loop) stats_.reason = "no candidate passed verification";
  return loop;
}

bool LoopDetector::addKeyframe(const LoopKeyframe& keyframe) {
  if (!keyframe.cloud) {
    logger_.warnOnce("loop_null_cloud", "loop detection: keyframe without cloud ignored");
    return false;
  }
  if (!entries_.empty() && keyframe.accum_distance < entries_.back().accum_distance) {
    logger_.warnOnce("loop_accum_order",
                     "loop detection: keyframe " + std::to_string(keyframe.id) +
                         " has a smaller accumulated distance than its predecessor; ignored");
    return false;
  }
  // Searched just before (process()): its descriptor and downsampled cloud are this keyframe's.
  LastQuery searched;
  if (keyframe.cloud == last_query_.input) searched = std::move(last_query_);
  last_query_ = LastQuery();
  const PointCloudConstPtr stored =
      searched.stored ? searched.stored
                      : storedCloud(keyframe.cloud, params_.voxel_size, pclVoxelFilter());
  if (static_cast<int>(stored->size()) < params_.min_points) {
    logger_.warnOnce("loop_few_points",
                     "loop detection: keyframe " + std::to_string(keyframe.id) + " has only " +
                         std::to_string(stored->size()) +
                         " valid points after downsampling; not stored (reported once)");
    return false;
  }
  LoopDatabaseEntry entry;
  const uint64_t index = entries_.size();
  entry.cloud = StoredCloud(clouds_, 2 * index, stored);
  entry.id = keyframe.id;
  entry.odom_pose = keyframe.odom_pose;
  entry.accum_distance = keyframe.accum_distance;
  entry.descriptor = searched.descriptor
                         ? *searched.descriptor
                         : computeScanContext(*keyframe.cloud, params_.scan_context);
  // Without a coarse stage no coarse cloud is needed: share the stored one.
  entry.coarse_cloud =
      coarse_registration_
          ? StoredCloud(clouds_, 2 * index + 1,
                        downsampleForLoop(*stored, params_.coarse_voxel_size, pclVoxelFilter()))
          : entry.cloud;
  // Numbered like entries_: the landmark source's index is the database index.
  if (landmark_source_) landmark_source_->add(keyframe.cloud);
  const Eigen::Vector3f position = keyframe.odom_pose.translation().cast<float>();
  ring_key_index_->add(entry.descriptor.ring_key.data());
  position_index_->add(position.data());
  entries_.push_back(std::move(entry));
  return true;
}

size_t LoopDetector::updatePoses(const std::vector<std::pair<uint64_t, Eigen::Isometry3d>>& poses) {
  std::unordered_map<uint64_t, const Eigen::Isometry3d*> by_id;
  by_id.reserve(poses.size());
  for (const auto& [id, pose] : poses) by_id[id] = &pose;
  size_t moved = 0;
  auto index = std::make_unique<DynamicKdIndex>(3);
  for (auto& entry : entries_) {
    const auto it = by_id.find(entry.id);
    if (it != by_id.end()) {
      entry.odom_pose = *it->second;
      ++moved;
    }
    const Eigen::Vector3f position = entry.odom_pose.translation().cast<float>();
    index->add(position.data());
  }
  position_index_ = std::move(index);
  return moved;
}

std::optional<DetectedLoop> LoopDetector::process(const LoopKeyframe& keyframe) {
  auto loop = detect(keyframe);
  LoopQueryStats stats = stats_;
  if (addKeyframe(keyframe) && landmark_source_) {
    // Extracted here when the query stopped before the hierarchy (no odometry candidates).
    stats.landmark_extraction_ms += landmark_source_->lastStats().extraction_ms;
    stats.landmarks = landmark_source_->lastStats().landmarks;
  }
  stats_ = stats;
  return loop;
}

}  // namespace osm_graph_slam
