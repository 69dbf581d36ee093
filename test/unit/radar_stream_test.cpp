// The radar_odometry nodelet's core (radar_stream.h): fromMulranImage converts an in-memory polar
// image exactly as readMulranPolarPng converts the file and names what is wrong with a bad one;
// RadarOdometryStream drops bad and out-of-order images (counted), restarts after a gap with zero
// velocity and the pose kept, and follows simulated sweeps.
#include <gtest/gtest.h>

#include <filesystem>

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
  sim::SimulationParams sp;
  sp.seed = 5;
  sp.route.length = 200.0;
  sp.city.blocks_x = sp.city.blocks_y = 4;
  sim::UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(sp, &error)) << error;
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 5);

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
  sim::SimulationParams sp;
  sp.seed = 5;
  sp.route.length = 200.0;
  sp.city.blocks_x = sp.city.blocks_y = 4;
  sim::UrbanSimulator world;
  std::string error;
  ASSERT_TRUE(world.build(sp, &error)) << error;
  const sim::RadarSimulator radar(world, sim::NavtechModel(), 5);
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
