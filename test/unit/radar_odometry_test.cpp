// Radar front-end (RadART-SLAM): the velocity estimator on synthetic skewed features, the
// Doppler correction, the MulRan polar PNG round trip and its errors, config/radar.yaml, and the
// odometry on the 10 real Oxford Radar RobotCar scan pairs (skipped without ../shared/data).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "osm_graph_slam/eval/radar_evaluation.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/radar/radar_motion.h"
#include "osm_graph_slam/radar/radar_odometry.h"
#include "osm_graph_slam/radar/radar_scan.h"
#include "test_data.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::radar;

namespace {

/// Landmarks seen from a sensor moving with the constant twist w; each observation's time is
/// the time its azimuth is swept (a 0.25 s turn starting at sweep_start). Returns measured
/// range and direction, with the range shortened by beta * (v . dir) (what eq. 7.9 undoes) and
/// gaussian noise; a fraction of the pairs are outliers (the second point replaced).
std::vector<RadarCorrespondence> skewedCorrespondences(const Eigen::Vector3d& w, double beta,
                                                       double noise, double outlier_fraction,
                                                       uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-60.0, 60.0), unit(0.0, 1.0);
  std::normal_distribution<double> n(0.0, noise);
  const double period = 0.25;
  // Sweep k observes bearing phi (in the sensor frame at that time) at k*period + phi/(2
  // pi)*period.
  auto observe = [&](const Eigen::Vector2d& landmark, double sweep_start, double& range,
                     Eigen::Vector2d& dir, double& t) {
    // Fixed point on the bearing's time (the sensor turns while it moves).
    t = sweep_start;
    for (int it = 0; it < 20; ++it) {
      const Eigen::Vector2d p = se2Exp(w, t).inverse() * landmark;
      double phi = std::atan2(p.y(), p.x());
      if (phi < 0) phi += 2 * M_PI;
      t = sweep_start + period * phi / (2 * M_PI);
    }
    const Eigen::Vector2d p = se2Exp(w, t).inverse() * landmark;
    dir = p.normalized();
    range = p.norm() - beta * w.head<2>().dot(dir) + n(rng);
  };
  std::vector<RadarCorrespondence> cs;
  while (cs.size() < 400) {
    const Eigen::Vector2d landmark(u(rng), u(rng));
    if (landmark.norm() < 5.0) continue;
    RadarCorrespondence c;
    observe(landmark, 0.0, c.range1, c.dir1, c.t1);
    observe(landmark, period, c.range2, c.dir2, c.t2);
    if (unit(rng) < outlier_fraction) {
      c.range2 = 5.0 + 50.0 * unit(rng);
      const double a = 2 * M_PI * unit(rng);
      c.dir2 = Eigen::Vector2d(std::cos(a), std::sin(a));
    }
    cs.push_back(c);
  }
  return cs;
}

double relativeError(const Eigen::Vector3d& est, const Eigen::Vector3d& truth) {
  return (est - truth).norm() / truth.norm();
}

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "/radar_odometry_test_" + name;
}

}  // namespace

TEST(RadarMotion, Se2ExpLogRoundTrip) {
  const Eigen::Vector3d w(9.0, -0.4, 0.6);
  const Eigen::Isometry2d T = se2Exp(w, 0.25);
  EXPECT_NEAR((se2Log(T) / 0.25 - w).norm(), 0.0, 1e-12);
  // A pure rotation rate with forward speed traces an arc: chord at angle theta/2.
  const Eigen::Isometry2d arc = se2Exp(Eigen::Vector3d(10.0, 0.0, 1.0), 1.0);
  EXPECT_NEAR(std::atan2(arc.translation().y(), arc.translation().x()), 0.5, 1e-12);
  EXPECT_NEAR(arc.translation().norm(), 2 * 10.0 * std::sin(0.5), 1e-12);
}

// The target: a known (v, omega) from synthetic skewed features within 1 %.
TEST(RadarMotion, RecoversKnownVelocityFromSkewedFeatures) {
  const Eigen::Vector3d w(10.0, 0.3, 0.5);  // 36 km/h, 29 deg/s: strong skew over a 0.25 s turn
  MotionEstimatorParams p;
  p.doppler_correction = false;
  const auto cs = skewedCorrespondences(w, 0.0, 0.02, 0.25, 3);
  const MotionEstimate est = estimateVelocity(cs, p, {0.125, 0.375});
  ASSERT_TRUE(est.ok);
  EXPECT_LT(relativeError(est.velocity, w), 0.01) << est.velocity.transpose();
  EXPECT_NEAR(est.velocity.z(), w.z(), 0.01 * std::abs(w.z()));
  EXPECT_GT(est.inliers.size(), 280u);  // 75 % of 400 are true
  EXPECT_LT(est.inliers.size(), 320u);
  // Without motion compensation the same data gives a visibly wrong velocity.
  p.motion_compensation = false;
  const MotionEstimate skewed = estimateVelocity(cs, p, {0.125, 0.375});
  if (skewed.ok) EXPECT_GT(relativeError(skewed.velocity, w), 0.02) << skewed.velocity.transpose();
}

TEST(RadarMotion, DopplerCorrectionInvertsTheShift) {
  const Eigen::Vector2d v(12.0, -1.0), dir = Eigen::Vector2d(0.6, 0.8);
  const double beta = 0.049, truth = 37.25;
  const double measured = truth - beta * v.dot(dir);  // the simulator's model
  EXPECT_NEAR(dopplerCorrectedRange(measured, dir, v, beta), truth, 1e-12);
  EXPECT_NEAR(truth - measured, beta * (12.0 * 0.6 - 1.0 * 0.8), 1e-12);
  // In the estimator: Doppler-shifted features give the right velocity only with the correction.
  const Eigen::Vector3d w(12.0, 0.0, 0.2);
  const auto cs = skewedCorrespondences(w, beta, 0.01, 0.2, 5);
  MotionEstimatorParams p;
  p.doppler_beta = beta;
  const MotionEstimate corrected = estimateVelocity(cs, p, {0.125, 0.375}, w * 0.9);
  ASSERT_TRUE(corrected.ok);
  EXPECT_LT(relativeError(corrected.velocity, w), 0.01) << corrected.velocity.transpose();
  // Uncorrected, the shift (up to beta |v| = 0.59 m) is nearly the same in both sweeps of a
  // landmark and mostly cancels: the velocity is off by a few per mille only (measured 0.46 %),
  // still several times the corrected error; the map points themselves are off by the full shift.
  p.doppler_correction = false;
  const MotionEstimate uncorrected = estimateVelocity(cs, p, {0.125, 0.375});
  ASSERT_TRUE(uncorrected.ok);
  EXPECT_GT(relativeError(uncorrected.velocity, w), 0.003) << uncorrected.velocity.transpose();
  EXPECT_GT(relativeError(uncorrected.velocity, w), 3 * relativeError(corrected.velocity, w));
}

TEST(RadarScan, MulranPolarPngRoundTripAndErrors) {
  RadarPolarScan s;
  s.num_azimuths = 400;
  s.num_bins = 3360;
  s.power.resize(size_t(s.num_azimuths) * s.num_bins);
  for (size_t i = 0; i < s.power.size(); ++i) s.power[i] = uint8_t((i * 7) % 251);
  const std::string path = tempPath("1000000000.png");
  std::string error;
  ASSERT_TRUE(writeMulranPolarPng(path, s, &error)) << error;
  const MulranPolarResult r = readMulranPolarPng(path, 1000000000, 500000000);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.scan.power, s.power);
  EXPECT_NEAR(r.scan.stamp, 0.5, 1e-12);
  EXPECT_NEAR(r.scan.times.back() - r.scan.times.front(), 0.25 * 399 / 400, 1e-12);
  EXPECT_NEAR(r.scan.azimuths[100], M_PI / 2, 1e-12);
  EXPECT_NEAR(r.scan.range_resolution, 0.0595238, 1e-9);

  // Truncated: the first half of the file.
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string half = tempPath("half.png");
  std::ofstream(half, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size() / 2));
  const MulranPolarResult t = readMulranPolarPng(half, 1, 0);
  EXPECT_FALSE(t.ok);
  EXPECT_NE(t.error.find("truncated PNG"), std::string::npos) << t.error;
  EXPECT_NE(t.error.find(half), std::string::npos) << t.error;
  // Wrong size, missing file, not a PNG.
  MulranPolarLayout layout;
  layout.expected_bins = 3768;
  const MulranPolarResult w = readMulranPolarPng(path, 1, 0, layout);
  EXPECT_FALSE(w.ok);
  EXPECT_NE(w.error.find("wrong size 3360 x 400"), std::string::npos) << w.error;
  EXPECT_NE(readMulranPolarPng(tempPath("none.png"), 1, 0).error.find("missing file"),
            std::string::npos);
  const std::string text = tempPath("text.png");
  std::ofstream(text) << "hello";
  EXPECT_NE(readMulranPolarPng(text, 1, 0).error.find("not a PNG"), std::string::npos);
}

TEST(RadarConfig, YamlEqualsTheDefaults) {
  const YamlParamReader yaml = YamlParamReader::fromFile(test::sourceDir() + "/config/radar.yaml");
  ASSERT_TRUE(yaml.ok()) << yaml.error();
  RadarOdometryParams read;
  read.features.detector = "changed";
  read.features.k_strongest = -1;
  read.motion.doppler_beta = -1;
  std::string error;
  ASSERT_TRUE(readParams(yaml, read, &error)) << error;
  const RadarOdometryParams d;
  EXPECT_EQ(read.features.detector, d.features.detector);
  EXPECT_EQ(read.features.k_strongest, d.features.k_strongest);
  EXPECT_EQ(read.features.min_power, d.features.min_power);
  EXPECT_EQ(read.features.cfar_train_cells, d.features.cfar_train_cells);
  EXPECT_EQ(read.features.cfar_guard_cells, d.features.cfar_guard_cells);
  EXPECT_DOUBLE_EQ(read.features.cfar_scale, d.features.cfar_scale);
  EXPECT_EQ(read.features.cfar_min_power, d.features.cfar_min_power);
  EXPECT_DOUBLE_EQ(read.features.min_range, d.features.min_range);
  EXPECT_DOUBLE_EQ(read.features.max_range, d.features.max_range);
  EXPECT_DOUBLE_EQ(read.features.thinning_cell, d.features.thinning_cell);
  EXPECT_EQ(read.features.max_features, d.features.max_features);
  EXPECT_DOUBLE_EQ(read.features.cart_resolution, d.features.cart_resolution);
  EXPECT_EQ(read.features.orb_patch_size, d.features.orb_patch_size);
  EXPECT_EQ(read.features.azimuth_clockwise, d.features.azimuth_clockwise);
  EXPECT_EQ(read.motion.motion_compensation, d.motion.motion_compensation);
  EXPECT_EQ(read.motion.doppler_correction, d.motion.doppler_correction);
  EXPECT_DOUBLE_EQ(read.motion.doppler_beta, d.motion.doppler_beta);
  EXPECT_EQ(read.motion.ransac_iterations, d.motion.ransac_iterations);
  EXPECT_DOUBLE_EQ(read.motion.inlier_threshold, d.motion.inlier_threshold);
  EXPECT_EQ(read.motion.gauss_newton_iterations, d.motion.gauss_newton_iterations);
  EXPECT_EQ(read.motion.min_inliers, d.motion.min_inliers);
  EXPECT_EQ(read.motion.seed, d.motion.seed);
  EXPECT_DOUBLE_EQ(read.ratio_test, d.ratio_test);
  EXPECT_DOUBLE_EQ(read.keyframe_translation, d.keyframe_translation);
  EXPECT_DOUBLE_EQ(read.keyframe_rotation_deg, d.keyframe_rotation_deg);
  // Every key of the file is read (a misspelt key would silently do nothing).
  EXPECT_EQ(read.registration.enabled, d.registration.enabled);
  EXPECT_EQ(read.registration.submap_keyframes, d.registration.submap_keyframes);
  EXPECT_DOUBLE_EQ(read.registration.max_correspondence, d.registration.max_correspondence);
  EXPECT_DOUBLE_EQ(read.registration.huber, d.registration.huber);
  // 39 of the odometry (14 registration/*), 22 of the back-end (graph/*, loop/*), 15 of GNSS
  // and gyro (gnss/*, imu/*), 13 of the radar_odometry nodelet (input/* with
  // gnss_unknown_sigma and nav_buffer, frames with radar_map_frame, nav_queue_size);
  // config_consistency_test audits all of them.
  EXPECT_EQ(yaml.keys().size(), 89u);
  const YamlParamReader bad = YamlParamReader::fromString("features:\n  detector: cfra\n");
  RadarOdometryParams p;
  EXPECT_FALSE(readParams(bad, p, &error));
  EXPECT_NE(error.find("cfra"), std::string::npos) << error;
}

// The 10 consecutive real Oxford pairs against radar_odometry.csv (doc/radar.md has the table).
TEST(RadarOdometryReal, OxfordPairsAgainstGroundTruth) {
  const std::string dir = test::sharedDataPath("oxford_radar");
  OGS_REQUIRE_SHARED_FILE(dir + "/radar.timestamps");
  OGS_REQUIRE_SHARED_FILE(dir + "/radar_odometry.csv");
  for (const std::string detector : {"kstrongest", "cfar"}) {
    RadarOdometryParams p;
    p.features.detector = detector;
    const OxfordEvaluation ev = evaluateOxfordDrive(dir, dir + "/radar_odometry.csv", p);
    ASSERT_TRUE(ev.ok) << ev.error;
    ASSERT_EQ(ev.pairs.size(), 10u);
    for (const OxfordPairError& e : ev.pairs) {
      EXPECT_TRUE(e.estimated) << detector << " pair " << e.destination_stamp_us;
      EXPECT_LT(e.translation_error, 0.25) << detector << " pair " << e.destination_stamp_us;
      EXPECT_LT(e.rotation_error * 180 / M_PI, 0.5) << detector;
      EXPECT_GT(e.inliers, 30) << detector;
    }
    // Measured 0.084 / 0.082 m, 0.14 / 0.12 deg, 2.2 / 1.6 % (k-strongest / CFAR).
    EXPECT_LT(ev.mean_translation_error, 0.12) << detector;
    EXPECT_LT(ev.mean_rotation_error_deg, 0.25) << detector;
    EXPECT_LT(ev.drift_percent, 3.5) << detector;
    EXPECT_NEAR(ev.gt_length, 19.41, 0.01);
  }
}
