// The radar_odometry nodelet's core (radar_stream.h): fromMulranImage converts an in-memory polar
// image exactly as readMulranPolarPng converts the file and names what is wrong with a bad one;
// RadarOdometryStream drops bad and out-of-order images (counted), restarts after a gap with zero
// velocity and the pose kept, and follows simulated sweeps.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/radar/radar_stream.h"
#include "osm_graph_slam/sim/radar_sim.h"

namespace fs = std::filesystem;
using namespace osm_graph_slam;
using namespace osm_graph_slam::radar;

namespace {

RadarPolarScan patternScan(int rows, int cols) {
  RadarPolarScan s;
  s.num_azimuths = rows;
  s.num_bins = cols;
  s.power.resize(size_t(rows) * cols);
  for (size_t i = 0; i < s.power.size(); ++i) s.power[i] = uint8_t((i * 7) % 251);
  return s;
}

PolarImageView viewOf(const RadarPolarScan& s) {
  PolarImageView v;
  v.data = s.power.data();
  v.size = s.power.size();
  v.rows = s.num_azimuths;
  v.cols = s.num_bins;
  v.step = size_t(s.num_bins);
  return v;
}

/// The world of the stream tests: seed 5, a 200 m route through 4 x 4 blocks.
void buildStreamWorld(sim::UrbanSimulator& world) {
  sim::SimulationParams sp;
  sp.seed = 5;
  sp.route.length = 200.0;
  sp.city.blocks_x = sp.city.blocks_y = 4;
  std::string error;
  ASSERT_TRUE(world.build(sp, &error)) << error;
}

}  // namespace

TEST(RadarStream, FromMulranImageEqualsThePngReader) {
  const RadarPolarScan s = patternScan(400, 3360);
  const std::string path =
      (fs::path(::testing::TempDir()) / "radar_stream_test_1500000000.png").string();
  std::string error;
  ASSERT_TRUE(writeMulranPolarPng(path, s, &error)) << error;
  const MulranPolarResult file = readMulranPolarPng(path, 1500000000, 1000000000);
  ASSERT_TRUE(file.ok) << file.error;
  const MulranPolarResult memory = fromMulranImage(viewOf(s), 0.5);
  ASSERT_TRUE(memory.ok) << memory.error;
  EXPECT_EQ(memory.scan.power, file.scan.power);
  EXPECT_EQ(memory.scan.azimuths, file.scan.azimuths);
  EXPECT_EQ(memory.scan.times, file.scan.times);
  EXPECT_DOUBLE_EQ(memory.scan.stamp, 0.5);
  EXPECT_DOUBLE_EQ(memory.scan.range_resolution, file.scan.range_resolution);
  EXPECT_NEAR(memory.scan.midTime(), 0.5 + 0.5 * 0.25 * 399 / 400, 1e-12);

  // A padded row step (4 extra bytes per row) gives the same scan.
  std::vector<uint8_t> padded(size_t(400) * 3364, 0);
  for (int a = 0; a < 400; ++a)
    std::copy(s.row(a), s.row(a) + 3360, padded.begin() + size_t(a) * 3364);
  PolarImageView v = viewOf(s);
  v.data = padded.data();
  v.size = padded.size();
  v.step = 3364;
  v.encoding = "8UC1";
  const MulranPolarResult p = fromMulranImage(v, 0.5);
  ASSERT_TRUE(p.ok) << p.error;
  EXPECT_EQ(p.scan.power, s.power);
}

TEST(RadarStream, FromMulranImageNamesTheProblem) {
  const RadarPolarScan s = patternScan(400, 3360);
  auto error = [](const PolarImageView& v) {
    const MulranPolarResult r = fromMulranImage(v, 0.0);
    EXPECT_FALSE(r.ok);
    return r.error;
  };
  EXPECT_NE(error(PolarImageView()).find("empty image"), std::string::npos);
  PolarImageView v = viewOf(s);
  v.encoding = "rgb8";
  EXPECT_NE(error(v).find("encoding 'rgb8'"), std::string::npos) << error(v);
  const RadarPolarScan narrow = patternScan(400, 1000);
  EXPECT_NE(error(viewOf(narrow)).find("wrong size 1000 x 400"), std::string::npos)
      << error(viewOf(narrow));
  v = viewOf(s);
  v.step = 3000;
  EXPECT_NE(error(v).find("row step 3000"), std::string::npos) << error(v);
  v = viewOf(s);
  v.size -= 1;
  EXPECT_NE(error(v).find("bytes"), std::string::npos) << error(v);
  // Any size when the layout does not fix one.
  MulranPolarLayout any;
  any.expected_azimuths = any.expected_bins = 0;
  EXPECT_TRUE(fromMulranImage(viewOf(narrow), 0.0, any).ok);
}

TEST(RadarStream, ParamsAreCheckedAndRead) {
  const YamlParamReader yaml = YamlParamReader::fromString(
      "input:\n  azimuths: 200\n  bins: 1000\n  rotation_period: 0.5\n  max_gap: 10.0\n");
  ASSERT_TRUE(yaml.ok()) << yaml.error();
  RadarStreamParams p;
  std::string error;
  ASSERT_TRUE(readParams(yaml, p, &error)) << error;
  EXPECT_EQ(p.layout.expected_azimuths, 200);
  EXPECT_EQ(p.layout.expected_bins, 1000);
  EXPECT_DOUBLE_EQ(p.layout.rotation_period, 0.5);
  EXPECT_DOUBLE_EQ(p.max_gap, 10.0);
  EXPECT_DOUBLE_EQ(p.layout.range_resolution, MulranPolarLayout().range_resolution);
  const YamlParamReader bad = YamlParamReader::fromString("input:\n  max_gap: -1.0\n");
  RadarStreamParams q;
  EXPECT_FALSE(readParams(bad, q, &error));
  EXPECT_NE(error.find("input/max_gap"), std::string::npos) << error;
}

// Simulated sweeps through the stream, with every kind of bad input in between.
TEST(RadarStream, DropsBadInputRestartsAfterAGapAndFollowsTheSweeps) {
  sim::UrbanSimulator world;
  ASSERT_NO_FATAL_FAILURE(buildStreamWorld(world));
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 5);
  std::string error;

  RadarOdometryStream stream{RadarOdometryParams(), RadarStreamParams()};
  const int64_t t0 = 1700000000000000000;  // a UNIX stamp [ns]
  auto stamp = [&](size_t k) { return t0 + int64_t(k) * 250000000; };
  std::vector<RadarPolarScan> sweeps;
  for (size_t k = 0; k < 12; ++k) sweeps.push_back(radar.simulate(40 + k));  // at speed

  Eigen::Isometry2d last_pose = Eigen::Isometry2d::Identity();
  for (size_t k = 0; k < 6; ++k) {
    const RadarStreamResult r = stream.process(viewOf(sweeps[k]), stamp(k));
    ASSERT_TRUE(r.has_step) << r.message;
    EXPECT_EQ(r.event, RadarStreamEvent::kProcessed);
    EXPECT_EQ(r.step.first, k == 0);
    EXPECT_TRUE(r.step.ok);
    // The reference time is the mid time of the sweep, on the input clock.
    EXPECT_EQ(r.time_ns, stamp(k) + int64_t(std::llround(0.125 * 399 / 400 * 1e9)));
    last_pose = r.step.pose;
  }
  // Bad images and old stamps: dropped, counted, no step.
  const RadarPolarScan narrow = patternScan(400, 1000);
  RadarStreamResult r = stream.process(viewOf(narrow), stamp(6));
  EXPECT_EQ(r.event, RadarStreamEvent::kBadImage);
  EXPECT_FALSE(r.has_step);
  r = stream.process(PolarImageView(), stamp(6));
  EXPECT_EQ(r.event, RadarStreamEvent::kBadImage);
  r = stream.process(viewOf(sweeps[2]), stamp(2));
  EXPECT_EQ(r.event, RadarStreamEvent::kOutOfOrder);
  EXPECT_NE(r.message.find("not newer"), std::string::npos) << r.message;
  r = stream.process(viewOf(sweeps[5]), stamp(5));  // the same stamp again
  EXPECT_EQ(r.event, RadarStreamEvent::kOutOfOrder);
  // The stream goes on after them.
  r = stream.process(viewOf(sweeps[6]), stamp(6));
  ASSERT_TRUE(r.has_step);
  EXPECT_TRUE(r.step.ok);
  EXPECT_GT(r.step.velocity.x(), 3.0);  // the route's cruise speed is 6-8 m/s
  last_pose = r.step.pose;

  // 30 s without a sweep: restart with zero velocity at the same pose, then matching again.
  const int64_t gap = 30000000000;
  r = stream.process(viewOf(sweeps[7]), stamp(7) + gap);
  ASSERT_TRUE(r.has_step);
  EXPECT_EQ(r.event, RadarStreamEvent::kRestarted);
  EXPECT_NE(r.message.find("restarted"), std::string::npos) << r.message;
  EXPECT_TRUE(r.step.first);
  EXPECT_EQ(r.step.velocity, Eigen::Vector3d::Zero());
  EXPECT_TRUE(r.step.pose.isApprox(last_pose));
  r = stream.process(viewOf(sweeps[8]), stamp(8) + gap);
  ASSERT_TRUE(r.has_step);
  EXPECT_EQ(r.event, RadarStreamEvent::kProcessed);
  EXPECT_TRUE(r.step.ok);
  EXPECT_GT(r.step.velocity.x(), 3.0);

  const RadarStreamCounters& c = stream.counters();
  EXPECT_EQ(c.received, 13u);
  EXPECT_EQ(c.processed, 9u);
  EXPECT_EQ(c.bad_images, 2u);
  EXPECT_EQ(c.out_of_order, 2u);
  EXPECT_EQ(c.gaps, 1u);
  EXPECT_EQ(c.ransac_failures, 0u);
  EXPECT_GT(c.ms_mean, 0.0);
}

// The stream drives RadarSlam: without loops the corrected pose is the odometry's; with loops
// enabled a gap restarts the odometry inside RadarSlam and the keyframe graph goes on (the pose
// continues, the next keyframe hangs from the last one).
TEST(RadarStream, RunsRadarSlamAndKeepsTheGraphThroughAGap) {
  sim::UrbanSimulator world;
  ASSERT_NO_FATAL_FAILURE(buildStreamWorld(world));
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 5);
  std::string error;
  std::vector<RadarPolarScan> sweeps;
  for (size_t k = 0; k < 16; ++k) sweeps.push_back(radar.simulate(40 + k));
  const int64_t t0 = 1700000000000000000;
  const int64_t gap = 30000000000;
  auto stamp = [&](size_t k) { return t0 + int64_t(k) * 250000000 + (k >= 8 ? gap : 0); };

  RadarOdometryStream odometry_only{RadarOdometryParams(), RadarStreamParams()};
  EXPECT_FALSE(odometry_only.loopsEnabled());
  RadarSlamParams slam_params;
  ASSERT_TRUE(slam_params.loop.enabled);
  RadarOdometryStream slam{slam_params, RadarStreamParams()};
  EXPECT_TRUE(slam.loopsEnabled());
  size_t keyframes_before_gap = 0;
  for (size_t k = 0; k < sweeps.size(); ++k) {
    const RadarStreamResult a = odometry_only.process(viewOf(sweeps[k]), stamp(k));
    const RadarStreamResult b = slam.process(viewOf(sweeps[k]), stamp(k));
    ASSERT_TRUE(a.has_step && b.has_step) << k;
    EXPECT_EQ(a.event, b.event) << k;
    EXPECT_EQ(b.event, k == 8 ? RadarStreamEvent::kRestarted : RadarStreamEvent::kProcessed);
    // The same odometry in both; no loop on 4 s of driving: the correction is identity.
    EXPECT_TRUE(a.step.pose.isApprox(b.step.pose, 1e-9)) << k;
    EXPECT_TRUE(a.corrected.isApprox(a.step.pose, 1e-12)) << k;
    EXPECT_TRUE(b.corrected.isApprox(b.step.pose, 1e-9)) << k;
    EXPECT_EQ(b.new_loops, 0);
    EXPECT_EQ(b.time_ns, slam.toInputTime(slam.slam().sweepTimes().back()));
    if (k == 7) keyframes_before_gap = slam.slam().numKeyframes();
  }
  // The first sweep after the gap is a keyframe of the same graph (restart keeps it), and the
  // corrected sweep poses run on across the gap where the odometry's pose does.
  EXPECT_GT(slam.slam().numKeyframes(), keyframes_before_gap + 1);
  const std::vector<Eigen::Isometry2d> poses = slam.slam().sweepPoses();
  ASSERT_EQ(poses.size(), sweeps.size());
  EXPECT_LT((poses[8].translation() - poses[7].translation()).norm(), 1e-9);
  EXPECT_GT(slam.counters().ms_loop_per_keyframe, 0.0);
  EXPECT_EQ(slam.counters().gaps, 1u);
  EXPECT_EQ(slam.slam().loopStats().accepted, 0);
}

// GNSS and gyro before the first sweep: held (in arrival order), handed over with the first
// sweep but for what is more than nav_buffer older than it (counted), the invalid ones counted
// and never handed over; a stream without loops ignores them (counted).
TEST(RadarStream, NavigationBeforeTheFirstSweepIsHeldForItAndCounted) {
  sim::UrbanSimulator world;
  ASSERT_NO_FATAL_FAILURE(buildStreamWorld(world));
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 5);
  std::string error;
  const RadarPolarScan sweep = radar.simulate(40);
  const int64_t t0 = 1700000000000000000;  // the first sweep's stamp [ns]
  const int64_t ms = 1000000;

  RadarSlamParams slam_params;
  RadarStreamParams stream_params;
  ASSERT_DOUBLE_EQ(stream_params.nav_buffer, 1.0);
  RadarOdometryStream stream{slam_params, stream_params};
  // 100 Hz yaw rates and 10 Hz fixes from 2 s before the first sweep to 0.5 s after it.
  stream.addGnssFix(t0 - 3000 * ms, 10.0, 10.0, 0.0, 0.5, false);  // no fix: not the origin
  for (int j = 0; j <= 250; ++j) {
    const int64_t stamp = t0 + (j - 200) * 10 * ms;
    stream.addYawRate(stamp, 0.01);
    if (j % 10 == 0)  // the last one without a covariance (sigma unknown)
      stream.addGnssFix(stamp, 49.011 + j * 1e-6, 8.417, 115.0, j == 250 ? -1.0 : 0.5);
  }
  stream.addYawRate(t0 - 500 * ms, 0.0, false);  // an Imu without rates
  stream.addYawRate(t0 - 400 * ms, std::nan(""));
  {
    const RadarStreamCounters& c = stream.counters();
    EXPECT_EQ(c.imu_received, 253u);
    EXPECT_EQ(c.imu_invalid, 2u);
    EXPECT_EQ(c.gnss_received, 27u);
    EXPECT_EQ(c.gnss_invalid, 1u);
    EXPECT_EQ(c.gnss_unknown_sigma, 1u);
    EXPECT_EQ(c.nav_buffered, 0u);
    EXPECT_EQ(c.nav_dropped_early, 0u);
    EXPECT_EQ(stream.slam().navStats().imu_samples, 0);  // nothing handed over yet
    EXPECT_EQ(stream.slam().navStats().gnss_fixes, 0);
    // The ENU origin is the first valid fix, not the invalid one before it.
    ASSERT_TRUE(stream.enu().has_value());
    EXPECT_DOUBLE_EQ(stream.enu()->originLat(), 49.011);
    EXPECT_DOUBLE_EQ(stream.enu()->originLon(), 8.417);
  }
  ASSERT_TRUE(stream.process(viewOf(sweep), t0).has_step);
  {
    // Older than t0 - 1 s: 100 rates (j < 100) and 10 fixes dropped; 151 rates and 16 fixes
    // (j = 100 .. 250, the one at exactly t0 - 1 s kept) handed over.
    const RadarStreamCounters& c = stream.counters();
    EXPECT_EQ(c.nav_dropped_early, 110u);
    EXPECT_EQ(c.nav_buffered, 167u);
    const RadarNavStats& n = stream.slam().navStats();
    EXPECT_EQ(n.imu_samples, 151);
    EXPECT_EQ(n.gnss_fixes, 16);
    EXPECT_EQ(n.gnss_rejected_sigma, 0);  // the unknown sigma is 5 m, below gnss/max_sigma
    EXPECT_EQ(n.imu_out_of_order + n.gnss_out_of_order, 0);
  }
  // After the first sweep: straight to the back-end; older than the last one: out of order there.
  stream.addYawRate(t0 + 510 * ms, 0.01);
  stream.addYawRate(t0 + 505 * ms, 0.01);
  EXPECT_EQ(stream.slam().navStats().imu_samples, 152);
  EXPECT_EQ(stream.slam().navStats().imu_out_of_order, 1);
  EXPECT_EQ(stream.counters().nav_buffered, 167u);

  // More than 4096 before the first sweep: the oldest go (counted) as they come.
  RadarOdometryStream flood{slam_params, stream_params};
  for (int j = 0; j < 5000; ++j) flood.addYawRate(t0 - (4999 - j) * 10 * ms, 0.01);
  EXPECT_EQ(flood.counters().nav_dropped_early, 5000u - 4096u);
  ASSERT_TRUE(flood.process(viewOf(sweep), t0).has_step);
  EXPECT_EQ(flood.counters().nav_buffered, 101u);  // t0 - 1 s .. t0
  EXPECT_EQ(flood.counters().nav_dropped_early, 4899u);
  EXPECT_EQ(flood.slam().navStats().imu_samples, 101);

  // Pure odometry: navigation is not used (the back-end's result is the odometry's).
  RadarOdometryStream odometry{RadarOdometryParams(), stream_params};
  odometry.addYawRate(t0, 0.01);
  odometry.addGnssFix(t0, 49.011, 8.417, 115.0, 0.5);
  EXPECT_EQ(odometry.counters().nav_ignored, 2u);
  EXPECT_FALSE(odometry.enu().has_value());
  ASSERT_TRUE(odometry.process(viewOf(sweep), t0).has_step);
  EXPECT_EQ(odometry.counters().nav_buffered, 0u);
  EXPECT_EQ(odometry.slam().navStats().imu_samples, 0);

  // The parameters: a non-positive unknown sigma or a negative buffer is refused.
  const YamlParamReader bad =
      YamlParamReader::fromString("input:\n  gnss_unknown_sigma: 0.0\n  nav_buffer: -1.0\n");
  RadarStreamParams q;
  EXPECT_FALSE(readParams(bad, q, &error));
  EXPECT_NE(error.find("input/gnss_unknown_sigma"), std::string::npos) << error;
}

// Fixes (the true radar position as latitude / longitude) and yaw rates fed with simulated
// sweeps as a bag would deliver them: the fixes reach the graph in ENU around the first valid
// fix and on the sweeps' clock, so the anchor maps each sweep's true position (converted as the
// fixes were) onto its corrected pose; a clock or conversion error of a sweep's length would put
// them metres apart.
TEST(RadarStream, GnssFixesReachTheGraphInEnuOnTheSweepsClock) {
  sim::UrbanSimulator world;
  ASSERT_NO_FATAL_FAILURE(buildStreamWorld(world));
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 5);
  std::string error;
  const size_t first = 40, n = 48;
  const double sim0 = radar.sweepStart(first);  // stream time 0 = simulator time sim0
  const int64_t t0 = 1700000000000000000;
  auto stamp = [&](double t) { return t0 + std::llround(t * 1e9); };  // stream time -> stamp
  auto geodetic = [&](double t) {
    return world.enu().toGeodetic(radar.radarPose(sim0 + t).translation());
  };
  auto yawRate = [&](double t) {
    const double h = 1e-3;
    const Eigen::AngleAxisd turn(radar.radarPose(sim0 + t - h).linear().transpose() *
                                 radar.radarPose(sim0 + t + h).linear());
    return (turn.axis() * turn.angle()).z() / (2 * h);
  };

  RadarOdometryStream stream{RadarSlamParams(), RadarStreamParams()};
  stream.addGnssFix(stamp(-0.9), 0.0, 0.0, 0.0, 0.5, false);  // no fix
  stream.addGnssFix(stamp(-0.85), std::nan(""), 8.4, 0.0, 0.5);
  // 10 Hz fixes and 100 Hz rates from 0.5 s before the first sweep, each up to 0.5 s past the
  // start of the sweep that follows them [ms].
  int fix_ms = -500, rate_ms = -500;
  std::vector<Eigen::Vector3d> fixes;
  for (size_t k = 0; k < n; ++k) {
    const int start_ms = 250 * int(k);
    for (; fix_ms <= start_ms + 500; fix_ms += 100) {
      const Eigen::Vector3d g = geodetic(fix_ms * 1e-3);
      stream.addGnssFix(stamp(fix_ms * 1e-3), g.x(), g.y(), g.z(), 0.3);
      fixes.push_back(g);
    }
    for (; rate_ms <= start_ms + 500; rate_ms += 10)
      stream.addYawRate(stamp(rate_ms * 1e-3), yawRate(rate_ms * 1e-3));
    ASSERT_TRUE(stream.process(viewOf(radar.simulate(first + k)), stamp(start_ms * 1e-3)).has_step)
        << k;
  }
  stream.finish();  // as at the end of a bag: the last fixes are in the graph, optimised
  ASSERT_TRUE(stream.enu().has_value());
  EXPECT_DOUBLE_EQ(stream.enu()->originLat(), fixes.front().x());  // the first valid fix
  EXPECT_DOUBLE_EQ(stream.enu()->originLon(), fixes.front().y());
  // ENU is metric: the distances between fixes are the simulator's.
  const Eigen::Vector3d a = stream.enu()->toEnu(fixes.front().x(), fixes.front().y(),
                                                fixes.front().z()),
                        b = stream.enu()->toEnu(fixes.back().x(), fixes.back().y(),
                                                fixes.back().z());
  const double true_distance = (radar.radarPose(sim0 + (fix_ms - 100) * 1e-3).translation() -
                                radar.radarPose(sim0 - 0.5).translation())
                                   .norm();
  EXPECT_NEAR((b - a).norm(), true_distance, 0.01);
  EXPECT_GT(true_distance, 40.0);

  const RadarStreamCounters& c = stream.counters();
  EXPECT_EQ(c.gnss_invalid, 2u);
  EXPECT_EQ(c.nav_buffered, 5u + 50u + 6u + 51u);  // -0.5 .. +0.5 s, before the first sweep
  EXPECT_EQ(c.nav_dropped_early, 0u);
  const RadarNavStats& nav = stream.slam().navStats();
  EXPECT_EQ(nav.gnss_fixes, int(fixes.size()));
  EXPECT_TRUE(nav.anchored);
  EXPECT_GT(nav.gnss_edges, 5);
  EXPECT_GT(nav.imu_edges, 5);
  EXPECT_EQ(nav.imu_missing, 0);
  const std::optional<Eigen::Isometry2d> map_from_enu = stream.slam().mapFromEnu();
  ASSERT_TRUE(map_from_enu.has_value());
  const std::vector<Eigen::Isometry2d> poses = stream.slam().sweepPoses();
  const std::vector<double>& times = stream.slam().sweepTimes();
  ASSERT_EQ(poses.size(), n);
  double worst = 0.0, rms = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d g = geodetic(times[k]);
    const Eigen::Vector2d enu = stream.enu()->toEnu(g.x(), g.y(), g.z()).head<2>();
    const double e = ((*map_from_enu) * enu - poses[k].translation()).norm();
    worst = std::max(worst, e);
    rms += e * e;
  }
  rms = std::sqrt(rms / double(n));
  std::printf(
      "[ RESULT   ] %d fixes, %d GNSS edges, %d yaw edges; sweeps vs anchored truth: rms %.3f m, "
      "max %.3f m\n",
      nav.gnss_fixes, nav.gnss_edges, nav.imu_edges, rms, worst);
  EXPECT_LT(rms, 0.3);
  EXPECT_LT(worst, 0.6);
}
