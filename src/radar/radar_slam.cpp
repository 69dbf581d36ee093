#include "osm_graph_slam/radar/radar_slam.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <unordered_set>

#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/common/timing.h"
#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam::radar {
namespace {

using Clock = std::chrono::steady_clock;
constexpr int kAnchorId = 1 << 30;  // the ENU frame's vertex; keyframes count up from 0
constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d diagonalInformation(double sigma_xy, double sigma_yaw) {
  return Eigen::Vector3d(1.0 / (sigma_xy * sigma_xy), 1.0 / (sigma_xy * sigma_xy),
                         1.0 / (sigma_yaw * sigma_yaw))
      .asDiagonal();
}

/// One point per cell (the first seen): submaps of overlapping keyframes repeat every wall.
std::vector<Eigen::Vector2d> thinToGrid(const std::vector<Eigen::Vector2d>& points, double cell) {
  std::unordered_set<int64_t> taken;
  std::vector<Eigen::Vector2d> out;
  out.reserve(points.size());
  for (const Eigen::Vector2d& p : points) {
    const int64_t cx = int64_t(std::floor(p.x() / cell)) + (1 << 20);
    const int64_t cy = int64_t(std::floor(p.y() / cell)) + (1 << 20);
    if (taken.insert((cx << 21) | cy).second) out.push_back(p);
  }
  return out;
}

}  // namespace

ScanContext radarScanContext(const std::vector<Eigen::Vector2d>& points,
                             const std::vector<float>& powers, const ScanContextParams& params) {
  Eigen::MatrixXf cells =
      Eigen::MatrixXf::Zero(std::max(1, params.num_rings), std::max(1, params.num_sectors));
  for (size_t i = 0; i < points.size() && i < powers.size(); ++i) {
    int ring, sector;
    if (!scanContextCell(points[i].x(), points[i].y(), params, &ring, &sector)) continue;
    float& c = cells(ring, sector);
    c = std::max(c, std::clamp(powers[i] / 255.0f, 0.0f, 1.0f));
  }
  return scanContextFromCells(cells);
}

bool readSlamParams(const ParamReader& r, RadarSlamParams& p, std::string* error) {
  if (!readParams(r, p.odometry, error)) return false;
  RadarGraphParams& g = p.graph;
  r.param("graph/sigma_translation_per_m", g.sigma_translation_per_m);
  r.param("graph/sigma_yaw_deg_per_m", g.sigma_yaw_deg_per_m);
  r.param("graph/sigma_yaw_per_rad", g.sigma_yaw_per_rad);
  r.param("graph/min_sigma_translation", g.min_sigma_translation);
  r.param("graph/min_sigma_yaw_deg", g.min_sigma_yaw_deg);
  RadarLoopParams& l = p.loop;
  r.param("loop/enabled", l.enabled);
  r.param("loop/min_travel", l.min_travel);
  r.param("loop/search_radius", l.search_radius);
  r.param("loop/scan_context_threshold", l.scan_context_threshold);
  r.param("loop/max_candidates", l.max_candidates);
  r.param("loop/submap_travel", l.submap_travel);
  r.param("loop/max_rms", l.max_rms);
  r.param("loop/min_overlap", l.min_overlap);
  r.param("loop/gate_base", l.gate_base);
  r.param("loop/gate_fraction", l.gate_fraction);
  r.param("loop/sigma_translation", l.sigma_translation);
  r.param("loop/sigma_yaw_deg", l.sigma_yaw_deg);
  r.param("loop/kernel_width", l.kernel_width);
  r.param("loop/scan_context/num_rings", l.scan_context.num_rings);
  r.param("loop/scan_context/num_sectors", l.scan_context.num_sectors);
  r.param("loop/scan_context/max_radius", l.scan_context.max_radius);
  r.param("loop/scan_context/min_radius", l.scan_context.min_radius);
  RadarNavParams& n = p.nav;
  r.param("gnss/enabled", n.gnss_enabled);
  r.param("gnss/min_baseline", n.gnss_min_baseline);
  r.param("gnss/min_spacing", n.gnss_min_spacing);
  r.param("gnss/sigma_floor", n.gnss_sigma_floor);
  r.param("gnss/sigma_scale", n.gnss_sigma_scale);
  r.param("gnss/max_sigma", n.gnss_max_sigma);
  r.param("gnss/max_interval", n.gnss_max_interval);
  r.param("gnss/kernel_width", n.gnss_kernel_width);
  r.param("gnss/optimise_every", n.gnss_optimise_every);
  r.param("imu/enabled", n.imu_enabled);
  r.param("imu/gyro_noise_deg_sqrt_s", n.gyro_noise_deg_sqrt_s);
  r.param("imu/gyro_bias_deg_s", n.gyro_bias_deg_s);
  r.param("imu/gyro_bias_horizon_s", n.gyro_bias_horizon_s);
  r.param("imu/max_gap", n.imu_max_gap);
  r.param("imu/wait_s", n.wait_s);
  if (n.gnss_sigma_floor <= 0 || n.gnss_sigma_scale <= 0 || n.gnss_kernel_width <= 0 ||
      n.gnss_max_interval <= 0 || n.gnss_optimise_every < 1 || n.gyro_noise_deg_sqrt_s < 0 ||
      n.gyro_bias_deg_s < 0 || n.gyro_bias_horizon_s < 0 ||
      n.gyro_noise_deg_sqrt_s + n.gyro_bias_deg_s <= 0 || n.imu_max_gap <= 0 || n.wait_s < 0) {
    if (error)
      *error =
          "radar parameters: gnss/sigma_floor, sigma_scale, kernel_width, max_interval, "
          "optimise_every and imu/max_gap must be positive, imu/gyro_* and wait_s not negative";
    return false;
  }
  if (g.min_sigma_translation <= 0 || g.min_sigma_yaw_deg <= 0 || l.sigma_translation <= 0 ||
      l.sigma_yaw_deg <= 0 || l.kernel_width <= 0 || l.scan_context.num_rings < 1 ||
      l.scan_context.num_sectors < 1 || l.scan_context.max_radius <= 0) {
    if (error)
      *error =
          "radar parameters: graph/min_sigma_*, loop/sigma_*, loop/kernel_width and the scan "
          "context grid must be positive";
    return false;
  }
  return true;
}

RadarSlam::RadarSlam(const RadarSlamParams& params)
    : params_(params), odometry_(params.odometry), graph_(std::make_unique<PoseGraph>()) {}
RadarSlam::~RadarSlam() = default;

RadarOdometryStep RadarSlam::process(const RadarPolarScan& scan) {
  RadarOdometryStep step = odometry_.process(scan);
  if (!step.first) travel_ += step.relative.translation().norm();
  sweep_times_.push_back(step.time);
  sweep_odom_.push_back(step.pose);
  if (step.keyframe) addKeyframe(step);
  sweep_keyframe_.push_back(int(keyframes_.size()) - 1);
  if (!step.keyframe) attachNavigation(step.time, false);
  return step;
}

void RadarSlam::addKeyframe(const RadarOdometryStep& step) {
  const int k = int(keyframes_.size());
  Keyframe kf;
  kf.odom = step.pose;
  kf.travel = travel_;
  kf.time = step.time;
  kf.points = step.points;
  const auto t0 = Clock::now();
  std::vector<float> powers;
  powers.reserve(step.feature_set.features.size());
  for (const RadarFeature& f : step.feature_set.features) powers.push_back(f.power);
  kf.descriptor = radarScanContext(kf.points, powers, params_.loop.scan_context);
  stats_.ms_descriptor += msSince(t0);
  if (k == 0) {
    graph_->addVertexSE2(0, planarPose(kf.odom), true);
  } else {
    const Keyframe& prev = keyframes_.back();
    const Eigen::Isometry2d rel = prev.odom.inverse() * kf.odom;
    graph_->addVertexSE2(k, planarPose(estimate(k - 1) * rel));
    const RadarGraphParams& g = params_.graph;
    const double d = kf.travel - prev.travel;
    const double st = std::max(g.min_sigma_translation, g.sigma_translation_per_m * d);
    const double turned = std::abs(yawOf(rel));
    const double sy = std::max(g.min_sigma_yaw_deg, g.sigma_yaw_deg_per_m * d) * M_PI / 180.0 +
                      g.sigma_yaw_per_rad * turned;
    graph_->addEdgeSE2(k - 1, k, planarPose(rel), diagonalInformation(st, sy));
  }
  keyframes_.push_back(std::move(kf));
  attachNavigation(keyframes_.back().time, false);  // before the loop search: a better estimate
  if (params_.loop.enabled) searchLoops(k);
}

void RadarSlam::addGnssFix(double time, const Eigen::Vector2d& enu, double sigma) {
  if (!params_.nav.gnss_enabled) return;
  if (!fixes_.empty() && !(time > fixes_.back().first)) {
    ++nav_stats_.gnss_out_of_order;
    return;
  }
  ++nav_stats_.gnss_fixes;
  if (!std::isfinite(time) || !enu.allFinite() || !(sigma <= params_.nav.gnss_max_sigma)) {
    ++nav_stats_.gnss_rejected_sigma;  // no fix, dead reckoning, or NaN
    return;
  }
  fixes_.push_back({time, Eigen::Vector3d(enu.x(), enu.y(), std::max(0.0, sigma))});
}

void RadarSlam::addYawRate(double time, double rate) {
  if (!params_.nav.imu_enabled) return;
  if (!std::isfinite(time) || !std::isfinite(rate) ||
      (!rates_.empty() && !(time > rates_.back().first))) {
    ++nav_stats_.imu_out_of_order;
    return;
  }
  ++nav_stats_.imu_samples;
  rates_.push_back({time, rate});
}

void RadarSlam::attachNavigation(double now, bool final) {
  while (nav_next_ < keyframes_.size()) {
    const double t = keyframes_[nav_next_].time;
    // A source that never delivered does not hold a keyframe back.
    auto covered = [t](const auto& v) { return v.empty() || v.back().first >= t; };
    if (!final && now < t + params_.nav.wait_s && !(covered(fixes_) && covered(rates_))) break;
    attachYawRate(int(nav_next_));
    attachFix(int(nav_next_));
    ++nav_next_;
  }
  pruneNavigation();
}

void RadarSlam::attachYawRate(int k) {
  if (k < 1 || rates_.empty()) return;
  const double t0 = keyframes_[size_t(k - 1)].time, t1 = keyframes_[size_t(k)].time;
  const RadarNavParams& n = params_.nav;
  if (rates_.front().first > t0 || rates_.back().first < t1) {
    ++nav_stats_.imu_missing;
    return;
  }
  // The integral of the piecewise-linear rate over [t0, t1].
  double yaw = 0.0;
  for (size_t i = 1; i < rates_.size() && rates_[i - 1].first < t1; ++i) {
    const auto& [ta, ra] = rates_[i - 1];
    const auto& [tb, rb] = rates_[i];
    if (tb <= t0) continue;
    if (tb - ta > n.imu_max_gap) {
      ++nav_stats_.imu_missing;
      return;
    }
    const double a = std::max(ta, t0), b = std::min(tb, t1);
    auto rateAt = [&](double t) { return ra + (rb - ra) * (t - ta) / (tb - ta); };
    yaw += 0.5 * (rateAt(a) + rateAt(b)) * (b - a);
  }
  const double dt = t1 - t0;
  const double variance_deg2 = dt * (n.gyro_noise_deg_sqrt_s * n.gyro_noise_deg_sqrt_s +
                                     n.gyro_bias_deg_s * n.gyro_bias_deg_s * n.gyro_bias_horizon_s);
  const double sigma = std::max(1e-5, std::sqrt(variance_deg2) * kDeg);
  // An SE(2) edge that constrains only the yaw change: zero information on x and y.
  const Eigen::Matrix3d info = Eigen::Vector3d(0, 0, 1.0 / (sigma * sigma)).asDiagonal();
  graph_->addEdgeSE2(k - 1, k, Pose2(0, 0, yaw), info);
  ++nav_stats_.imu_edges;
}

void RadarSlam::attachFix(int k) {
  Keyframe& kf = keyframes_[size_t(k)];
  if (fixes_.empty() || kf.travel - last_fix_travel_ < params_.nav.gnss_min_spacing) return;
  const auto after = std::lower_bound(fixes_.begin(), fixes_.end(), kf.time,
                                      [](const auto& f, double t) { return f.first < t; });
  if (after == fixes_.end() || after == fixes_.begin() && after->first > kf.time) return;
  Eigen::Vector3d fix = after->second;
  if (after->first > kf.time) {  // interpolate between the fixes around the keyframe
    const auto before = std::prev(after);
    if (after->first - before->first > params_.nav.gnss_max_interval) return;
    const double w = (kf.time - before->first) / (after->first - before->first);
    fix = (1 - w) * before->second + w * after->second;
    fix.z() = std::max(before->second.z(), after->second.z());
  }
  kf.has_fix = true;
  kf.fix = fix.head<2>();
  kf.fix_sigma = std::max(params_.nav.gnss_sigma_floor, params_.nav.gnss_sigma_scale * fix.z());
  last_fix_travel_ = kf.travel;
  if (!graph_->hasVertex(kAnchorId)) {
    if (anchor()) optimise();
    return;
  }
  addFixEdge(k);
  if (++fixes_since_optimise_ >= params_.nav.gnss_optimise_every) optimise();
}

bool RadarSlam::anchor() {
  // The fit p_map = R p_enu + t over the keyframes with a fix, once they span the baseline.
  std::vector<int> with_fix;
  for (int k = 0; k < int(keyframes_.size()); ++k)
    if (keyframes_[size_t(k)].has_fix) with_fix.push_back(k);
  if (with_fix.size() < 2) return false;
  double span = 0;
  const Eigen::Vector2d first = keyframes_[size_t(with_fix.front())].fix;
  for (int k : with_fix) span = std::max(span, (keyframes_[size_t(k)].fix - first).norm());
  if (span < params_.nav.gnss_min_baseline) return false;
  std::vector<Eigen::Vector2d> enu, map;
  for (int k : with_fix) {
    enu.push_back(keyframes_[size_t(k)].fix);
    map.push_back(estimate(k).translation());
  }
  graph_->addVertexSE2(kAnchorId, planarPose(fitRigid2d(enu, map)));
  nav_stats_.anchored = true;
  for (int k : with_fix) addFixEdge(k);
  return true;
}

void RadarSlam::addFixEdge(int k) {
  // Anchor -> keyframe with the fix as translation: e = A^-1 p_k - z; the yaw is free.
  const Keyframe& kf = keyframes_[size_t(k)];
  const double w = 1.0 / (kf.fix_sigma * kf.fix_sigma);
  EdgeOptions options;
  options.kernel = RobustKernel::huber(params_.nav.gnss_kernel_width);
  graph_->addEdgeSE2(kAnchorId, k, Pose2(kf.fix.x(), kf.fix.y(), 0.0),
                     Eigen::Vector3d(w, w, 0).asDiagonal(), options);
  ++nav_stats_.gnss_edges;
}

void RadarSlam::pruneNavigation() {
  // Keep what the undecided keyframes can still use: rates from the last decided keyframe on,
  // fixes from the one before the first undecided keyframe.
  if (keyframes_.empty()) return;
  const size_t last = std::min(nav_next_, keyframes_.size()) - (nav_next_ > 0 ? 1 : 0);
  const double t = keyframes_[last].time;
  auto prune = [t](auto& v) {
    size_t keep = 0;
    while (keep + 1 < v.size() && v[keep + 1].first <= t) ++keep;
    v.erase(v.begin(), v.begin() + std::ptrdiff_t(keep));
  };
  prune(rates_);
  prune(fixes_);
}

Eigen::Isometry2d RadarSlam::estimate(int k) const {
  const std::optional<Pose2> p = graph_->vertexSE2(k);
  return p ? isometry2dFromPlanar(*p) : keyframes_[size_t(k)].odom;
}

std::vector<Eigen::Vector2d> RadarSlam::submap(int center, bool past_only) const {
  const Keyframe& c = keyframes_[size_t(center)];
  const Eigen::Isometry2d to_center = c.odom.inverse();
  std::vector<Eigen::Vector2d> out;
  for (int k = center;
       k >= 0 && c.travel - keyframes_[size_t(k)].travel <= params_.loop.submap_travel; --k) {
    const Eigen::Isometry2d T = to_center * keyframes_[size_t(k)].odom;
    for (const Eigen::Vector2d& p : keyframes_[size_t(k)].points) out.push_back(T * p);
  }
  if (!past_only)
    for (int k = center + 1; k < int(keyframes_.size()) &&
                             keyframes_[size_t(k)].travel - c.travel <= params_.loop.submap_travel;
         ++k) {
      const Eigen::Isometry2d T = to_center * keyframes_[size_t(k)].odom;
      for (const Eigen::Vector2d& p : keyframes_[size_t(k)].points) out.push_back(T * p);
    }
  return thinToGrid(out, 0.5);
}

void RadarSlam::searchLoops(int query) {
  const RadarLoopParams& lp = params_.loop;
  const Keyframe& q = keyframes_[size_t(query)];
  ++stats_.keyframes_searched;
  auto t0 = Clock::now();
  const Eigen::Isometry2d eq = estimate(query);
  struct Candidate {
    int index;
    double score;  // metres (odometry) or descriptor distance
    bool by_descriptor;
    Eigen::Isometry2d guess;
  };
  std::vector<Candidate> near, similar;
  for (int j = 0; j < query; ++j) {
    const Keyframe& c = keyframes_[size_t(j)];
    if (q.travel - c.travel < lp.min_travel) break;  // keyframes are in travel order
    const Eigen::Isometry2d ej = estimate(j);
    const double d = (ej.translation() - eq.translation()).norm();
    if (d < lp.search_radius) near.push_back({j, d, false, ej.inverse() * eq});
    const ScanContextMatch m = matchScanContexts(q.descriptor, c.descriptor, lp.scan_context);
    if (m.distance < lp.scan_context_threshold) {
      // The descriptor only knows the yaw: p_candidate = Rz(yaw) p_query, same place.
      Eigen::Isometry2d guess = Eigen::Isometry2d::Identity();
      guess.linear() = Eigen::Rotation2Dd(m.yaw).toRotationMatrix();
      similar.push_back({j, m.distance, true, guess});
    }
  }
  auto byScore = [](const Candidate& a, const Candidate& b) { return a.score < b.score; };
  std::sort(near.begin(), near.end(), byScore);
  std::sort(similar.begin(), similar.end(), byScore);
  std::vector<Candidate> candidates;
  for (size_t i = 0;
       int(candidates.size()) < lp.max_candidates && (i < near.size() || i < similar.size()); ++i) {
    if (i < near.size()) candidates.push_back(near[i]);
    if (i < similar.size() && int(candidates.size()) < lp.max_candidates)
      candidates.push_back(similar[i]);
  }
  stats_.ms_search += msSince(t0);
  stats_.candidates += int(candidates.size());
  for (const Candidate& c : candidates) {
    t0 = Clock::now();
    RadarLoop loop;
    const bool ok = verify(query, c.index, c.guess, loop);
    stats_.ms_verify += msSince(t0);
    ++stats_.verified;
    if (!ok) {
      ++stats_.rejected_registration;
      continue;
    }
    // Gate: the loop may not move the query further than the odometry can have drifted.
    const Eigen::Isometry2d predicted = estimate(c.index).inverse() * eq;
    const double jump = (predicted.translation() - loop.measurement.translation()).norm();
    const double travel = q.travel - keyframes_[size_t(c.index)].travel;
    if (jump > lp.gate_base + lp.gate_fraction * travel) {
      ++stats_.rejected_gate;
      continue;
    }
    loop.by_scan_context = c.by_descriptor;
    EdgeOptions options;
    options.kernel = RobustKernel::cauchy(lp.kernel_width);
    graph_->addEdgeSE2(loop.from, loop.to, planarPose(loop.measurement),
                       diagonalInformation(lp.sigma_translation, lp.sigma_yaw_deg * M_PI / 180.0),
                       options);
    loops_.push_back(loop);
    ++stats_.accepted;
    optimise();
    break;  // one loop per keyframe; the next keyframes add more where the revisit goes on
  }
}

bool RadarSlam::verify(int query, int candidate, const Eigen::Isometry2d& guess, RadarLoop& loop) {
  const RadarLoopParams& lp = params_.loop;
  PlanarPointMap target;
  RadarRegistrationParams rp = params_.odometry.registration;
  target.build(submap(candidate, false), rp);
  const std::vector<Eigen::Vector2d> source = submap(query, true);
  if (source.empty() || target.size() == 0) return false;
  RadarAlignment a;
  a.pose = guess;
  for (double radius : {4.0, 2.0, 1.0}) {  // coarse to fine: the guess may be metres off
    rp.max_correspondence = radius;
    a = target.align(source, a.pose, rp);
    if (!a.ok) return false;
  }
  loop.from = candidate;
  loop.to = query;
  loop.from_time = keyframes_[size_t(candidate)].time;
  loop.to_time = keyframes_[size_t(query)].time;
  loop.measurement = a.pose;
  loop.rms = a.rms;
  loop.overlap = double(a.correspondences) / double(source.size());
  return a.rms <= lp.max_rms && loop.overlap >= lp.min_overlap;
}

void RadarSlam::optimise() {
  const auto t0 = Clock::now();
  OptimizerOptions options;
  options.max_iterations = 50;
  graph_->optimize(INT_MAX, options);
  ++stats_.optimisations;
  fixes_since_optimise_ = 0;  // every optimisation counts, whatever triggered it
  stats_.ms_optimise += msSince(t0);
}

void RadarSlam::finish() {
  attachNavigation(std::numeric_limits<double>::infinity(), true);
  if (!loops_.empty() || graph_->hasVertex(kAnchorId) || nav_stats_.imu_edges > 0) optimise();
}

std::optional<Eigen::Isometry2d> RadarSlam::mapFromEnu() const {
  const std::optional<Pose2> a = graph_->vertexSE2(kAnchorId);
  if (!a) return std::nullopt;
  return isometry2dFromPlanar(*a);
}

Eigen::Isometry2d RadarSlam::mapToOdometry() const {
  if (keyframes_.empty()) return Eigen::Isometry2d::Identity();
  const int k = int(keyframes_.size()) - 1;
  return estimate(k) * keyframes_.back().odom.inverse();
}

std::vector<Eigen::Isometry2d> RadarSlam::keyframePoses() const {
  std::vector<Eigen::Isometry2d> out;
  out.reserve(keyframes_.size());
  for (int k = 0; k < int(keyframes_.size()); ++k) out.push_back(estimate(k));
  return out;
}

std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> RadarSlam::loopSegments() const {
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> out;
  out.reserve(loops_.size());
  for (const RadarLoop& l : loops_)
    out.emplace_back(estimate(l.from).translation(), estimate(l.to).translation());
  return out;
}

std::vector<Eigen::Isometry2d> RadarSlam::sweepPoses() const {
  std::vector<Eigen::Isometry2d> out;
  out.reserve(sweep_odom_.size());
  for (size_t i = 0; i < sweep_odom_.size(); ++i) {
    const int k = std::max(0, sweep_keyframe_[i]);
    if (keyframes_.empty()) {
      out.push_back(sweep_odom_[i]);
      continue;
    }
    const Keyframe& kf = keyframes_[size_t(k)];
    out.push_back(estimate(k) * kf.odom.inverse() * sweep_odom_[i]);
  }
  return out;
}

}  // namespace osm_graph_slam::radar
