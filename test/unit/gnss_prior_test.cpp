// GNSS as evidence: with gnss_prior_std > 0 every keyframe's fix is a robust position prior and the
// first keyframe is no longer fixed at its own (noisy) fix; without, the whole trajectory carries
// the first fix's error.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "backend_test_utils.h"
#include "osm_graph_slam/common/logger.h"

using namespace osm_graph_slam;

namespace {

/// 20 keyframes 2 m apart along x (exact odometry); the first fix is 3 m off in y, the others
/// exact, one of them an outlier 30 m off. Returns the trajectory's mean |y| error.
double meanLateralError(double gnss_prior_std) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = gnss_prior_std;
  GraphBackend backend(params);
  for (uint64_t i = 0; i < 20; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.gnss_position = Eigen::Vector2d(2.0 * i, i == 0 ? 3.0 : (i == 10 ? 30.0 : 0.0));
    backend.addKeyframe(kf);
  }
  backend.update(true);
  double sum = 0.0;
  const Trajectory t = backend.trajectory();
  for (const auto& p : t) sum += std::abs(p.pose.translation().y());
  return sum / t.size();
}

}  // namespace

TEST(GnssPrior, FixesAverageOutTheFirstFixError) {
  const double fixed = meanLateralError(0.0), priors = meanLateralError(2.0);
  std::printf("[gnss_prior] mean lateral error: first keyframe fixed %.3f m, GNSS priors %.3f m\n",
              fixed, priors);
  EXPECT_NEAR(fixed, 3.0, 1e-6);  // the first fix's error everywhere
  EXPECT_LT(priors, 0.4);         // 19 good fixes outweigh it; the 30 m outlier is down-weighted
}

namespace {

/// 300 keyframes 2 m and 1 s apart along x (exact odometry); the fixes wander with a slowly
/// varying bias (1.2 m, period 120 s, across the track) plus white noise. Returns the RMS of
/// the trajectory's lateral error after its mean is removed: how much the shape follows the bias.
double lateralShapeError(double gnss_bias_std) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = 1.5;
  params.gnss.gnss_bias_std = gnss_bias_std;
  params.gnss.gnss_bias_tau = 60.0;
  GraphBackend backend(params);
  std::mt19937 rng(7);
  std::normal_distribution<double> white(0.0, 1.5);
  for (uint64_t i = 0; i < 300; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    const double bias = 1.2 * std::sin(2.0 * M_PI * i / 120.0);
    kf.gnss_position = Eigen::Vector2d(2.0 * i + white(rng), bias + white(rng));
    backend.addKeyframe(kf);
  }
  backend.update(true);
  const Trajectory t = backend.trajectory();
  double mean = 0.0, sq = 0.0;
  for (const auto& p : t) mean += p.pose.translation().y() / t.size();
  for (const auto& p : t) sq += std::pow(p.pose.translation().y() - mean, 2) / t.size();
  return std::sqrt(sq);
}

}  // namespace

TEST(GnssPrior, AnEstimatedBiasKeepsTheTrajectoryFromFollowingTheFixesWander) {
  const double independent = lateralShapeError(0.0), with_bias = lateralShapeError(1.0);
  std::printf("[gnss_prior] lateral shape error: fixes independent %.3f m, bias estimated %.3f m\n",
              independent, with_bias);
  EXPECT_GT(independent, 0.2);  // the odometry bends towards the wandering fixes
  EXPECT_LT(with_bias, independent / 2.0);
}

namespace {

/// 40 keyframes along x (exact odometry). The first 20 fixes are exact and report 0.02 m (RTK);
/// the last 20 lie 1 m to the left and report 1.8 m (single point, bias included). Returns the
/// trajectory's mean lateral offset.
double meanOffsetAfterRtkIsLost(bool reported_accuracy) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = 1.5;
  params.gnss.gnss_bias_std = 1.0;
  params.gnss.gnss_reported_accuracy = reported_accuracy;
  GraphBackend backend(params);
  for (uint64_t i = 0; i < 40; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.gnss_position = Eigen::Vector2d(2.0 * i, i < 20 ? 0.0 : 1.0);
    kf.gnss_std = i < 20 ? 0.02 : 1.8;
    backend.addKeyframe(kf);
  }
  backend.update(true);
  double sum = 0.0;
  const Trajectory t = backend.trajectory();
  for (const auto& p : t) sum += p.pose.translation().y() / t.size();
  return sum;
}

}  // namespace

// Each fix weighs what its receiver reports: RTK fixes (floored at gnss_min_reported_std) hold
// the trajectory; the single-point fixes after them cannot pull it, their offset is their bias.
TEST(GnssPrior, EachFixWeighsItsReportedAccuracy) {
  const double reported = meanOffsetAfterRtkIsLost(true),
               modelled = meanOffsetAfterRtkIsLost(false);
  std::printf(
      "[gnss_prior] mean offset after RTK is lost: reported accuracy %.3f m, modelled %.3f m\n",
      reported, modelled);
  EXPECT_LT(std::abs(reported), 0.03);
  EXPECT_GT(modelled, 0.15);  // all fixes alike: the trajectory moves towards the later ones
}

// A windowed update holds the GNSS biases of time windows before the window: a free old bias
// would keep every old fix in the problem.
TEST(GnssPrior, AWindowedUpdateHoldsTheBiasesOfOldTimeWindows) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = 1.5;
  params.gnss.gnss_bias_std = 1.0;
  params.gnss.gnss_bias_window = 10.0;
  params.odometry.odometry_scale_window = 0.0;
  params.schedule.optimization_window = 10;
  GraphBackend backend(params);
  BackendUpdateReport r;
  for (uint64_t i = 0; i < 60; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.gnss_position = Eigen::Vector2d(2.0 * i, 0.3);
    backend.addKeyframe(kf);
    r = backend.update();
  }
  ASSERT_TRUE(r.window_start);
  ASSERT_EQ(*r.window_start, 50u);
  // Keyframes 50-59 (stamps 51-60 s, bias window 5): 10 odometry edges, 10 fixes and the
  // Gauss-Markov step into window 5; nothing older (else 59 + 60 + 5 edges).
  EXPECT_EQ(r.phase1.num_edges, 21);
  // A forced update (save_map) frees everything again.
  r = backend.update(true);
  EXPECT_GE(r.phase1.num_edges, 59 + 60 + 5);
}

namespace {

/// 300 keyframes 2 m and 1 s apart on level ground (exact odometry). The map origin is the first
/// fix, whose altitude was 2 m too high: the truth is z = −2 m. The fixes' altitudes scatter by
/// 2.5 m about it. Returns the trajectory's mean |z| error.
double meanHeightError(double gnss_altitude_std, double gnss_bias_std) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = 1.5;
  params.gnss.gnss_altitude_std = gnss_altitude_std;
  params.gnss.gnss_bias_std = gnss_bias_std;
  GraphBackend backend(params);
  std::mt19937 rng(11);
  std::normal_distribution<double> white(0.0, 2.5);
  for (uint64_t i = 0; i < 300; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.gnss_position = Eigen::Vector2d(2.0 * i, 0.0);
    kf.gnss_altitude = i == 0 ? 0.0 : -2.0 + white(rng);
    backend.addKeyframe(kf);
  }
  backend.update(true);
  double sum = 0.0;
  const Trajectory t = backend.trajectory();
  for (const auto& p : t) sum += std::abs(p.pose.translation().z() + 2.0);
  return sum / t.size();
}

}  // namespace

TEST(GnssPrior, TheFixesAltitudeCorrectsTheOriginsHeight) {
  const double off = meanHeightError(0.0, 0.0), independent = meanHeightError(2.5, 0.0),
               with_bias = meanHeightError(2.5, 1.0);
  std::printf(
      "[gnss_prior] mean height error: altitude unused %.3f m, independent %.3f m, with"
      " the bias estimated %.3f m\n",
      off, independent, with_bias);
  EXPECT_NEAR(off, 2.0, 0.01);  // the first fix's altitude error everywhere
  EXPECT_LT(independent, 0.3);
  EXPECT_LT(with_bias, 0.6);  // the bias (1.5 m up) can explain part of the offset
}

namespace {

struct ScaleRun {
  double along_rms = 0.0;  ///< [m] RMS of the along-track error
  std::vector<double> scales;
};

/// 300 keyframes 2 m and 1 s apart along x whose odometry is 0.5 % short (a LiDAR range bias);
/// the fixes scatter by 1.5 m about the truth. The odometry's fitness makes it stiff along the
/// track (σ 2.3 cm per step), so without a scale the trajectory follows the odometry's length.
ScaleRun scaledOdometryRun(double odometry_scale_window) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = 1.5;
  params.odometry.odometry_scale_window = odometry_scale_window;
  GraphBackend backend(params);
  std::mt19937 rng(5);
  std::normal_distribution<double> white(0.0, 1.5);
  for (uint64_t i = 0; i < 300; ++i) {
    KeyframeInput kf = straightKeyframe(i);
    kf.odom_pose.translation() *= 0.995;
    kf.accum_distance *= 0.995;
    kf.gnss_position = Eigen::Vector2d(2.0 * i + white(rng), white(rng));
    backend.addKeyframe(kf);
  }
  backend.update(true);
  ScaleRun run;
  const Trajectory t = backend.trajectory();
  for (size_t i = 0; i < t.size(); ++i)
    run.along_rms += std::pow(t[i].pose.translation().x() - 2.0 * i, 2) / t.size();
  run.along_rms = std::sqrt(run.along_rms);
  run.scales = backend.odometryScales();
  return run;
}

}  // namespace

TEST(GnssPrior, AnEstimatedOdometryScaleRemovesALengthBias) {
  const ScaleRun off = scaledOdometryRun(0.0), on = scaledOdometryRun(100.0);
  std::printf(
      "[gnss_prior] along-track RMS error: scale fixed %.3f m, estimated %.3f m (%zu "
      "windows, first %.4f, last %.4f)\n",
      off.along_rms, on.along_rms, on.scales.size(), on.scales.front(), on.scales.back());
  EXPECT_TRUE(off.scales.empty());
  ASSERT_EQ(on.scales.size(), 6u);  // 597 m of odometry path in 100 m windows
  for (double s : on.scales) EXPECT_NEAR(s, 1.0 / 0.995, 1.5e-3);
  EXPECT_GT(off.along_rms, 0.15);  // measured 0.215 m: the fixes hold the ends, not the middle
  EXPECT_LT(on.along_rms, off.along_rms / 2.0);  // measured 0.064 m
}

TEST(GnssPrior, AnOdometryScaleFarFromOneIsLoggedOnce) {
  GraphBackendParams params = noOsmKnownHeading();
  params.gnss.gnss_prior_std = 1.5;
  params.odometry.odometry_scale_window = 100.0;
  std::vector<std::string> warnings;
  auto logger = std::make_shared<Logger>([&](LogLevel level, const std::string& msg) {
    if (level == LogLevel::kWarn) warnings.push_back(msg);
  });
  GraphBackend backend(params, logger);
  for (uint64_t i = 0; i < 150; ++i) {  // odometry 3 % short, exact fixes
    KeyframeInput kf = straightKeyframe(i);
    kf.odom_pose.translation() *= 0.97;
    kf.accum_distance *= 0.97;
    kf.gnss_position = Eigen::Vector2d(2.0 * i, 0.0);
    backend.addKeyframe(kf);
    if (i % 50 == 49) backend.update(true);
  }
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("odometry's scale is estimated at 1.0"), std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[0].find("shorter"), std::string::npos) << warnings[0];
}
