// Deskewing (cloud/scan_deskew.h): the time of each azimuth in a sweep, and a raw simulated
// sweep moved back to what a perfectly compensated one holds (the simulator's and the deskew's
// conventions agree: clockwise, cut behind the sensor, stamp when facing forward).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "osm_graph_slam/cloud/scan_deskew.h"
#include "osm_graph_slam/sim/simulator.h"

using namespace osm_graph_slam;

TEST(ScanDeskew, TimeOfEachAzimuthInTheSweep) {
  const SweepTiming cw;  // 0.1 s, clockwise, cut behind, stamp mid-sweep
  EXPECT_NEAR(sweepTimeOffset(10, 0, cw), 0.0, 1e-12);       // ahead: the stamp
  EXPECT_NEAR(sweepTimeOffset(0, 10, cw), -0.025, 1e-12);    // left: a quarter turn earlier
  EXPECT_NEAR(sweepTimeOffset(0, -10, cw), 0.025, 1e-12);    // right: a quarter turn later
  EXPECT_NEAR(sweepTimeOffset(-10, 1e-6, cw), -0.05, 1e-6);  // behind, left: the first column
  EXPECT_NEAR(sweepTimeOffset(-10, -1e-6, cw), 0.05, 1e-6);  // behind, right: the last
  SweepTiming ccw = cw;
  ccw.clockwise = false;
  EXPECT_NEAR(sweepTimeOffset(0, 10, ccw), 0.025, 1e-12);
  EXPECT_NEAR(sweepTimeOffset(0, -10, ccw), -0.025, 1e-12);
}

TEST(ScanDeskew, RawSimulatedSweepBecomesTheCompensatedOne) {
  sim::SimulationParams p;
  p.seed = 4;
  p.motion_distortion = true;
  sim::UrbanSimulator raw_sim, compensated_sim;
  ASSERT_TRUE(raw_sim.build(p));
  p.compensated_sweep = true;
  ASSERT_TRUE(compensated_sim.build(p));
  const size_t k = 60;  // cruising
  const sim::SimulatedScan raw = raw_sim.simulate(k), truth = compensated_sim.simulate(k);
  ASSERT_EQ(raw.cloud.size(), truth.cloud.size());  // same rays, only the frame differs
  ASSERT_GT(raw.cloud.size(), 10000u);

  // The true motion of the sensor over one period around the stamp (constant velocity).
  const double t = raw_sim.scanTime(k), period = 1.0 / p.lidar.rate_hz;
  const Eigen::Isometry3d motion =
      raw_sim.sensorPose(t - period / 2).inverse() * raw_sim.sensorPose(t + period / 2);
  ASSERT_GT(motion.translation().norm(), 0.3);  // the vehicle moves while the head turns
  PointCloud fixed = raw.cloud;
  SweepTiming timing;
  timing.period = period;
  deskewCloud(fixed, Eigen::Isometry3d::Identity(), motion, period, timing);

  std::vector<double> before, after;
  for (size_t i = 0; i < raw.cloud.size(); ++i) {
    const Eigen::Vector3f r = raw.cloud[i].getVector3fMap(), f = fixed[i].getVector3fMap(),
                          g = truth.cloud[i].getVector3fMap();
    before.push_back((r - g).norm());
    after.push_back((f - g).norm());
  }
  const auto p95 = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() * 95 / 100, v.end());
    return v[v.size() * 95 / 100];
  };
  EXPECT_GT(p95(before), 0.2) << "the raw sweep is distorted by the motion";
  EXPECT_LT(p95(after), 0.01) << "deskewed to within 1 cm";
}

// The sector-wise deskew of a full-resolution scan (the multi-cue tracker's) agrees with the
// per-point one: a sector lasts 49 us, so a fast sweep (10 m/s, 30 deg/s) differs by under 2 mm
// at 60 m, on both turning directions and with the cut away from behind the sensor.
TEST(ScanDeskew, BySectorMatchesPerPointDeskew) {
  PointCloud scan;
  for (int i = 0; i < 20000; ++i) {
    const double azimuth = -M_PI + 2.0 * M_PI * ((i * 7919) % 20000) / 20000.0;
    const double range = 2.0 + 58.0 * ((i * 104729) % 1000) / 1000.0;
    PointT p;
    p.x = static_cast<float>(range * std::cos(azimuth));
    p.y = static_cast<float>(range * std::sin(azimuth));
    p.z = static_cast<float>(-1.7 + 0.002 * (i % 500));
    scan.push_back(p);
  }
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  // over one 0.1 s period
  motion.linear() =
      Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d(0.1, 0.2, 1.0).normalized())
          .toRotationMatrix();
  motion.translation() = Eigen::Vector3d(1.0, 0.1, 0.02);
  for (const bool clockwise : {true, false})
    for (const double start : {M_PI, 0.7}) {
      SweepTiming timing;
      timing.clockwise = clockwise;
      timing.start_azimuth = start;
      const PointCloudPtr exact =
          deskewedCopy(scan, Eigen::Isometry3d::Identity(), motion, 0.1, timing);
      const PointCloudPtr sectors = deskewedScanBySector(scan, motion, 0.1, timing);
      ASSERT_EQ(exact->size(), sectors->size());
      double worst = 0.0;
      for (size_t i = 0; i < exact->size(); ++i)
        worst = std::max<double>(
            worst,
            (exact->points[i].getVector3fMap() - sectors->points[i].getVector3fMap()).norm());
      EXPECT_LT(worst, 0.002) << "clockwise " << clockwise << ", cut at " << start;
    }
}
