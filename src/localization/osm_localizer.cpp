#include "osm_graph_slam/localization/osm_localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/information.h"
#include "osm_graph_slam/localization/osm_wall_matcher.h"

namespace osm_graph_slam {

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kN = OsmLocalizer::kStateSize;
using VecN = Eigen::Matrix<double, kN, 1>;
using MatN = Eigen::Matrix<double, kN, kN>;
constexpr int kX = 0, kY = 1, kYaw = 2, kDx = 3, kDy = 4, kBx = 5, kBy = 6;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// Information-form EKF update with a linear(ised) measurement: works with a singular
/// information (a match along one street constrains only across it). Returns false (and
/// changes nothing) when the innovation's squared Mahalanobis distance exceeds gate_chi2.
template <int M>
bool informationUpdate(VecN& x, MatN& P, const Eigen::Matrix<double, M, kN>& H,
                       const Eigen::Matrix<double, M, 1>& innovation,
                       const Eigen::Matrix<double, M, M>& info, double gate_chi2) {
  using MatM = Eigen::Matrix<double, M, M>;
  // S⁻¹ = (H P Hᵀ + Λ⁻¹)⁻¹ = Λ (I + H P Hᵀ Λ)⁻¹, defined for a singular Λ as well.
  const MatM A = H * P * H.transpose();
  const MatM s_inv = info * (MatM::Identity() + A * info).inverse();
  const double d2 = innovation.dot(s_inv * innovation);
  if (!std::isfinite(d2) || d2 > gate_chi2) return false;
  const Eigen::Matrix<double, kN, M> K = P * H.transpose() * s_inv;
  x += K * innovation;
  P = (MatN::Identity() - K * H) * P;
  P = 0.5 * (P + P.transpose());
  return true;
}

/// One scan's walls against the map score lower than a keyframe's against one building (parked
/// cars, trees and unmapped walls count as unmatched): the localiser's own limits apply, and a
/// weak match counts little anyway (its information scales with the fitness).
LineMatcherParams withThresholds(LineMatcherParams m, const OsmLocalizerParams& p) {
  m.min_fitness = p.min_fitness;
  m.min_matched_segments = p.min_matched;
  return m;
}

}  // namespace

const char* toString(OsmLocalizationStatus status) {
  switch (status) {
    case OsmLocalizationStatus::kUninitialized:
      return "uninitialized";
    case OsmLocalizationStatus::kDeadReckoning:
      return "dead_reckoning";
    case OsmLocalizationStatus::kGnss:
      return "gnss";
    case OsmLocalizationStatus::kOsm:
      return "osm";
  }
  return "?";
}

struct OsmLocalizer::Impl {
  explicit Impl(OsmWallMatcher w) : walls(std::move(w)) {}
  OsmWallMatcher walls;
};

OsmLocalizer::OsmLocalizer(const OsmLocalizerParams& params, std::vector<Building> buildings,
                           const WallPointExtractorParams& walls,
                           const LineSegmentExtractorParams& segments,
                           const LineMatcherParams& matcher)
    : params_(params),
      impl_(std::make_unique<Impl>(OsmWallMatcher(std::move(buildings), walls, segments,
                                                  withThresholds(matcher, params)))) {}

OsmLocalizer::~OsmLocalizer() = default;

size_t OsmLocalizer::addBuildings(std::vector<Building> buildings) {
  return impl_->walls.addBuildings(std::move(buildings));
}

size_t OsmLocalizer::numBuildings() const {
  return impl_->walls.numBuildings();
}

void OsmLocalizer::initialize(const Eigen::Vector3d& pose, double position_std, double yaw_std) {
  state_.setZero();
  state_.head<3>() = pose;
  cov_.setZero();
  cov_(kX, kX) = cov_(kY, kY) = position_std * position_std;
  cov_(kYaw, kYaw) = yaw_std * yaw_std;
  cov_(kDx, kDx) = cov_(kDy, kDy) = params_.datum_std * params_.datum_std;
  cov_(kBx, kBx) = cov_(kBy, kBy) = params_.gnss_bias_std * params_.gnss_bias_std;
  initialized_ = true;
  since_match_ = 1e9;
}

OsmLocalizationOutput OsmLocalizer::process(double stamp, const Eigen::Isometry3d& odom_pose,
                                            const PointCloudConstPtr& cloud,
                                            const std::optional<Eigen::Vector2d>& gnss,
                                            std::optional<double> gnss_std,
                                            const std::optional<double>& yaw) {
  ++stats_.scans;
  const double fix_std = gnss_std.value_or(params_.gnss_std);
  if (!initialized_) {
    // The start needs a position (the fix) and a heading (the IMU's, else the walls').
    if (gnss && yaw) {
      initialize({gnss->x(), gnss->y(), *yaw}, fix_std, params_.init_yaw_std);
    } else if (!gnss || !params_.use_osm || !tryStartWithoutHeading(cloud, *gnss, fix_std)) {
      ++stats_.uninitialized;
      last_odom_ = odom_pose;
      return {};
    }
    last_odom_ = odom_pose;
    last_stamp_ = stamp;
    OsmLocalizationOutput out = output(odom_pose);
    out.status = OsmLocalizationStatus::kGnss;
    return out;
  }
  const auto t0 = Clock::now();
  predict(odom_pose, std::max(0.0, stamp - last_stamp_));
  last_stamp_ = stamp;
  OsmLocalizationOutput out;
  out.status = OsmLocalizationStatus::kDeadReckoning;
  if (params_.use_gnss && gnss) {
    if (correctGnss(*gnss, fix_std)) {
      out.status = OsmLocalizationStatus::kGnss;
      ++stats_.gnss_used;
    } else {
      ++stats_.gnss_rejected;
    }
  }
  stats_.filter_ms += msSince(t0);
  if (params_.use_osm && since_match_ >= params_.match_every_distance && cloud) {
    since_match_ = 0.0;
    correctOsm(cloud, out);
    if (out.osm_outcome == "accepted") out.status = OsmLocalizationStatus::kOsm;
  }
  const OsmLocalizationOutput pose = output(odom_pose);
  out.pose = pose.pose;
  out.covariance = pose.covariance;
  out.datum = pose.datum;
  return out;
}

void OsmLocalizer::predict(const Eigen::Isometry3d& odom_pose, double dt) {
  const Pose2 step =
      last_odom_ ? planarPose(*last_odom_).inverse() * planarPose(odom_pose) : Pose2();
  last_odom_ = odom_pose;
  const double dist = step.translation().norm();
  since_match_ += dist;
  const double yaw = state_(kYaw);
  const double c = std::cos(yaw), s = std::sin(yaw);
  MatN F = MatN::Identity();
  F(kX, kYaw) = -s * step.x - c * step.y;
  F(kY, kYaw) = c * step.x - s * step.y;
  state_(kX) += c * step.x - s * step.y;
  state_(kY) += s * step.x + c * step.y;
  state_(kYaw) = wrapAngle(yaw + step.theta);
  MatN Q = MatN::Zero();
  const double st = params_.odometry_std_per_m * dist + 1e-4;
  const double sy = params_.odometry_yaw_std_per_m * dist +
                    params_.odometry_yaw_std_per_rad * std::abs(step.theta) + 1e-5;
  const double sd = params_.datum_walk_std_per_m * dist;
  Q(kX, kX) = Q(kY, kY) = st * st;
  Q(kYaw, kYaw) = sy * sy;
  Q(kDx, kDx) = Q(kDy, kDy) = sd * sd;
  // The receiver's bias: first-order Gauss-Markov (decays towards 0, stationary deviation kept).
  if (params_.gnss_bias_tau > 0.0) {
    const double decay = std::exp(-dt / params_.gnss_bias_tau);
    F(kBx, kBx) = F(kBy, kBy) = decay;
    state_(kBx) *= decay;
    state_(kBy) *= decay;
    Q(kBx, kBx) = Q(kBy, kBy) =
        params_.gnss_bias_std * params_.gnss_bias_std * (1.0 - decay * decay);
  }
  cov_ = F * cov_ * F.transpose() + Q;
}

bool OsmLocalizer::correctGnss(const Eigen::Vector2d& fix, double std) {
  Eigen::Matrix<double, 2, kN> H = Eigen::Matrix<double, 2, kN>::Zero();
  H(0, kX) = H(1, kY) = 1.0;
  H(0, kBx) = H(1, kBy) = 1.0;  // a fix is where the vehicle is plus the receiver's bias
  const Eigen::Vector2d innovation = fix - state_.head<2>() - state_.segment<2>(kBx);
  const Eigen::Matrix2d info = Eigen::Matrix2d::Identity() / (std * std);
  return informationUpdate<2>(state_, cov_, H, innovation, info, params_.gnss_gate_chi2);
}

void OsmLocalizer::correctOsm(const PointCloudConstPtr& cloud, OsmLocalizationOutput& out) {
  out.osm_attempted = true;
  ++stats_.osm_attempts;
  auto t0 = Clock::now();
  const std::vector<LineSegment2> scan_segments = impl_->walls.scanWalls(*cloud);
  stats_.walls_ms += msSince(t0);
  if (static_cast<int>(scan_segments.size()) < params_.min_segments) {
    out.osm_outcome = "few_segments";
    ++stats_.osm_few_segments;
    return;
  }
  // The walls are matched in the OSM map's frame: there the vehicle is where it is plus the
  // map's offset (a map drawn 2 m east of the world shows the vehicle 2 m east too).
  const Pose2 guess(state_(kX) + state_(kDx), state_(kY) + state_(kDy), state_(kYaw));
  const std::vector<LineSegment2> map_segments =
      impl_->walls.wallsSeenFrom(guess.translation(), params_.query_radius);
  if (map_segments.empty()) {
    out.osm_outcome = "no_buildings";
    ++stats_.osm_no_buildings;
    return;
  }
  t0 = Clock::now();
  const LineMatchResult match =
      impl_->walls.matcher().matchGlobal(scan_segments, map_segments, guess);
  stats_.matching_ms += msSince(t0);
  out.osm_fitness = match.fitness;
  if (!match.success) {
    out.osm_outcome = "failed";
    out.osm_message = match.message;
    ++stats_.osm_failed;
    return;
  }
  if (match.fitness < params_.min_fitness || match.matched_segments < params_.min_matched) {
    out.osm_outcome = "weak";
    ++stats_.osm_weak;
    return;
  }
  // Information of the pose from the walls' pinning point (as the back-end's global priors).
  const Eigen::Matrix3d info =
      leverInformation(scaledInformation(match.information, params_.osm_std_xy, params_.osm_std_yaw,
                                         impl_->walls.matcher().params()),
                       match.matched_centre - match.transform.translation());
  Eigen::Matrix<double, 3, kN> H = Eigen::Matrix<double, 3, kN>::Zero();
  H(0, kX) = H(1, kY) = H(2, kYaw) = 1.0;
  H(0, kDx) = H(1, kDy) = 1.0;
  const Eigen::Vector3d innovation(match.transform.x - guess.x, match.transform.y - guess.y,
                                   wrapAngle(match.transform.theta - guess.theta));
  if (!informationUpdate<3>(state_, cov_, H, innovation, info, params_.osm_gate_chi2)) {
    out.osm_outcome = "gated";
    ++stats_.osm_gated;
    return;
  }
  state_(kYaw) = wrapAngle(state_(kYaw));
  out.osm_outcome = "accepted";
  ++stats_.osm_accepted;
}

bool OsmLocalizer::tryStartWithoutHeading(const PointCloudConstPtr& cloud,
                                          const Eigen::Vector2d& fix, double std) {
  if (!cloud) return false;
  const std::vector<LineSegment2> scan_segments = impl_->walls.scanWalls(*cloud);
  if (static_cast<int>(scan_segments.size()) < params_.min_segments) return false;
  const std::vector<LineSegment2> map_segments =
      impl_->walls.wallsSeenFrom(fix, params_.query_radius);
  if (map_segments.empty()) return false;
  const LineMatchResult match = impl_->walls.matcher().matchGlobal(
      scan_segments, map_segments, Pose2(fix.x(), fix.y(), 0.0), true);
  if (!match.success || match.fitness < params_.min_fitness ||
      match.matched_segments < params_.min_matched)
    return false;
  // Only the heading is taken from the walls; the position stays the fix's (the datum unknown).
  initialize({fix.x(), fix.y(), match.transform.theta}, std, params_.init_yaw_std);
  return true;
}

OsmLocalizationOutput OsmLocalizer::output(const Eigen::Isometry3d& odom_pose) const {
  OsmLocalizationOutput out;
  // Planar pose from the filter; height, roll and pitch from the odometry.
  const Eigen::Vector2d rp = rollPitchOf(Eigen::Matrix3d(odom_pose.rotation()));
  out.pose.linear() = rotationFromRollPitchYaw(rp.x(), rp.y(), state_(kYaw));
  out.pose.translation() = Eigen::Vector3d(state_(kX), state_(kY), odom_pose.translation().z());
  out.covariance = cov_.topLeftCorner<3, 3>();
  out.datum = state_.segment<2>(kDx);
  return out;
}

}  // namespace osm_graph_slam
