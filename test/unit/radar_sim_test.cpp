// Radar simulator (simulate_urban --sensor navtech): the MulRan-layout drive parses back with the
// project's MulRan readers, is byte-identical for the same seed, shifts ranges by the Doppler
// term that the front-end's correction undoes, and radar odometry on it follows the truth; a
// truncated PNG is reported and the drive continues.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "osm_graph_slam/io/mulran.h"
#include "osm_graph_slam/radar/radar_drive.h"
#include "osm_graph_slam/radar/radar_motion.h"
#include "osm_graph_slam/sim/radar_sim.h"

namespace fs = std::filesystem;
using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

SimulationParams shortDrive(uint64_t seed) {
  SimulationParams p;
  p.seed = seed;
  p.route.length = 200.0;
  p.city.blocks_x = 4;
  p.city.blocks_y = 4;
  return p;
}

std::string readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::string tempDir(const std::string& name) {
  const fs::path d = fs::path(::testing::TempDir()) / ("radar_sim_test_" + name);
  fs::remove_all(d);
  return d.string();
}

/// Per row, the bin of the strongest power within [min_bin, max_bin].
int strongestBin(const radar::RadarPolarScan& s, int row, int min_bin, int max_bin) {
  const uint8_t* p = s.row(row);
  return int(std::max_element(p + min_bin, p + max_bin) - p);
}

}  // namespace

TEST(RadarSim, MulranDriveParsesBackAndIsDeterministic) {
  UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(shortDrive(3), &error)) << error;
  NavtechModel model;
  model.max_scans = 12;  // keeps the test fast
  const RadarSimulator radar(world, model, 3);
  const size_t n = 12;
  ASSERT_GE(radar.numScans(), 40u);  // a 200 m route at <= 8 m/s lasts > 25 s

  // Two drives from the same seed.
  RadarDriveStats stats_a, stats_b;
  const std::string a = tempDir("a"), b = tempDir("b");
  ASSERT_TRUE(radar.writeMulranDrive(a, stats_a, {}, &error)) << error;
  const RadarSimulator again(world, model, 3);
  ASSERT_TRUE(again.writeMulranDrive(b, stats_b, {}, &error)) << error;
  EXPECT_EQ(stats_a.scans, n);

  MulranSequence seq;
  ASSERT_TRUE(readMulranSequence(a, seq, &error)) << error;
  std::vector<int64_t> radar_stamps;
  for (const MulranStamp& s : seq.stamps)
    if (s.sensor == "radar") radar_stamps.push_back(s.stamp_ns);
  ASSERT_EQ(radar_stamps.size(), n);
  EXPECT_EQ(stats_a.imu, 301u);  // 100 Hz over the 3 s of 12 sweeps, both ends
  EXPECT_EQ(radar_stamps[1] - radar_stamps[0], 250000000);  // 4 Hz
  EXPECT_EQ(seq.gps.size(), stats_a.gps);
  EXPECT_EQ(seq.imu.size(), stats_a.imu);
  EXPECT_TRUE(seq.imu.front().has_rates);
  EXPECT_EQ(seq.poses.size(), stats_a.poses);
  EXPECT_TRUE(std::is_sorted(
      seq.stamps.begin(), seq.stamps.end(),
      [](const MulranStamp& x, const MulranStamp& y) { return x.stamp_ns < y.stamp_ns; }));
  for (size_t k = 0; k < n; ++k) {
    const std::string path = seq.radarPolarPath(radar_stamps[k]);
    const radar::MulranPolarResult r = radar::readMulranPolarPng(path, radar_stamps[k], 0);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scan.num_azimuths, 400);
    EXPECT_EQ(r.scan.num_bins, 3360);
    // The file holds exactly what the simulator computed.
    EXPECT_EQ(r.scan.power, radar.simulate(k).power) << "sweep " << k;
    EXPECT_EQ(readBytes(path), readBytes(fs::path(b) / fs::relative(path, a))) << path;
  }
  // The yaw rate integrated over the 3 s is the true yaw change (global_pose) within the gyro's
  // white noise (0.1 deg/s per 100 Hz sample: 0.02 deg over 3 s) and the seed's bias (0 here).
  double integrated = 0;
  for (size_t i = 1; i < seq.imu.size(); ++i)
    integrated += 0.5 * (seq.imu[i].gyro.z() + seq.imu[i - 1].gyro.z()) *
                  double(seq.imu[i].stamp_ns - seq.imu[i - 1].stamp_ns) * 1e-9;
  auto yawOfPose = [](const Eigen::Isometry3d& P) {
    return std::atan2(P.linear()(1, 0), P.linear()(0, 0));
  };
  const double true_change = std::remainder(
      yawOfPose(seq.poses.back().pose) - yawOfPose(seq.poses.front().pose), 2 * M_PI);
  EXPECT_NEAR(integrated, true_change, 0.1 * M_PI / 180) << "true " << true_change;
  for (const std::string f : {"global_pose.csv", "sensor_data/gps.csv", "sensor_data/xsens_imu.csv",
                              "sensor_data/data_stamp.csv"})
    EXPECT_EQ(readBytes(fs::path(a) / f), readBytes(fs::path(b) / f)) << f;
  // Another seed: other noise.
  const RadarSimulator other(world, model, 4);
  EXPECT_NE(other.simulate(0).power, radar.simulate(0).power);

  // Power statistics: a noise floor near noise_mean, walls well above it, saturation respected.
  const radar::RadarPolarScan s = radar.simulate(5);
  double sum = 0;
  int strong = 0, max = 0;
  for (uint8_t p : s.power) {
    sum += p;
    strong += p > 80;
    max = std::max<int>(max, p);
  }
  EXPECT_NEAR(sum / s.power.size(), model.noise_mean, 1.5);
  EXPECT_GT(strong, 500);
  EXPECT_LE(max, model.saturation);
}

TEST(RadarSim, DopplerShiftIsWhatTheCorrectionUndoes) {
  UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(shortDrive(3), &error)) << error;
  NavtechModel with, without;
  without.doppler_beta = 0.0;
  with.noise_sigma = without.noise_sigma = 0.0;  // noise-free: the peak bin is exact
  with.speckle_sigma = without.speckle_sigma = 0.0;
  with.ghost_probability = without.ghost_probability = 0.0;
  const RadarSimulator a(world, with, 3), b(world, without, 3);
  // A sweep at cruise speed.
  size_t k = 40;
  while (k < a.numScans() && a.radarVelocity(a.sweepStart(k)).x() < 6.0) ++k;
  ASSERT_LT(k, a.numScans());
  const radar::RadarPolarScan sa = a.simulate(k), sb = b.simulate(k);
  int checked = 0;
  for (int row = 0; row < 400; ++row) {
    const int lo = 60, hi = 1600;  // 3.6 .. 95 m
    const int ba = strongestBin(sa, row, lo, hi), bb = strongestBin(sb, row, lo, hi);
    if (sb.row(row)[bb] < 60 || sa.row(row)[ba] < 60) continue;
    if (std::abs(ba - bb) > 20) continue;  // another target won in one of them
    if (std::min(ba, bb) < lo + 20 || std::max(ba, bb) > hi - 20) continue;  // lobe cut off
    const Eigen::Vector2d u = radar::beamDirection(sa.azimuths[row], true);
    const Eigen::Vector3d v = a.radarVelocity(sa.times[row]);
    const double measured = sa.binRange(ba), truth = sb.binRange(bb);
    // The shift is -beta v.u, and eq. 7.9 with the true velocity gives the range back.
    EXPECT_NEAR(measured - truth, -with.doppler_beta * v.head<2>().dot(u), 0.07) << "row " << row;
    EXPECT_NEAR(radar::dopplerCorrectedRange(measured, u, v.head<2>(), with.doppler_beta), truth,
                0.07)
        << "row " << row;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(RadarSim, OdometryFollowsTheTruthAndSurvivesATruncatedPng) {
  UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(shortDrive(5), &error)) << error;
  NavtechModel model;
  model.max_scans = 60;
  const RadarSimulator radar(world, model, 5);
  const std::string dir = tempDir("odometry");
  RadarDriveStats stats;
  ASSERT_TRUE(radar.writeMulranDrive(dir, stats, {}, &error)) << error;
  MulranSequence seq;
  ASSERT_TRUE(readMulranSequence(dir, seq, &error)) << error;
  std::vector<int64_t> stamps;
  for (const MulranStamp& s : seq.stamps)
    if (s.sensor == "radar") stamps.push_back(s.stamp_ns);
  // Truncate sweep 10: the drive goes on without it.
  const std::string victim = seq.radarPolarPath(stamps[10]);
  const std::string bytes = readBytes(victim);
  std::ofstream(victim, std::ios::binary | std::ios::trunc).write(bytes.data(), 1000);

  radar::RadarDriveOptions options;
  const radar::RadarDriveResult r =
      radar::runMulranRadarSlam(dir, radar::RadarSlamParams(), options);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.skipped.size(), 1u);
  EXPECT_NE(r.skipped[0].find("truncated PNG"), std::string::npos) << r.skipped[0];
  EXPECT_NE(r.skipped[0].find(victim), std::string::npos) << r.skipped[0];
  EXPECT_EQ(r.scans, 59);  // 60 written, one truncated
  EXPECT_EQ(r.failed, 0);
  ASSERT_EQ(r.ground_truth.size(), r.odometry.size());
  // Relative motion per sweep against the truth, and the end point after 60 sweeps.
  double sum = 0, length = 0, worst = 0;
  for (size_t k = 1; k < r.odometry.size(); ++k) {
    const Eigen::Isometry3d est = r.odometry[k - 1].pose.inverse() * r.odometry[k].pose;
    const Eigen::Isometry3d gt = r.ground_truth[k - 1].pose.inverse() * r.ground_truth[k].pose;
    const double e = (est.translation().head<2>() - gt.translation().head<2>()).norm();
    sum += e;
    worst = std::max(worst, e);
    length += gt.translation().head<2>().norm();
  }
  const double end =
      (r.odometry.back().pose.translation() - r.ground_truth.back().pose.translation())
          .head<2>()
          .norm();
  EXPECT_GT(length, 60.0);
  EXPECT_LT(sum / (r.odometry.size() - 1), 0.08);
  EXPECT_LT(worst, 0.6);  // the sweep after the gap spans 0.5 s
  EXPECT_LT(end / length, 0.05) << "end-point error " << end << " m of " << length << " m";
}
