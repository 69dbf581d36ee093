// SensorInputs: IMU attitude and GNSS fixes matched to keyframes by time, and the first
// keyframe's heading policy shared by the graph_backend nodelet and the offline drive readers.
#include <gtest/gtest.h>

#include <cmath>

#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/imu_reading_buffer.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/sensor_inputs.h"

namespace osm_graph_slam {
namespace {

Eigen::Quaterniond rpy(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(rotationFromRollPitchYaw(roll, pitch, yaw));
}

TEST(Attitude, RollPitchYawRoundTrip) {
  const Eigen::Matrix3d R = rotationFromRollPitchYaw(0.03, -0.02, 2.5);
  EXPECT_NEAR(rollPitchOf(R).x(), 0.03, 1e-12);
  EXPECT_NEAR(rollPitchOf(R).y(), -0.02, 1e-12);
  EXPECT_NEAR(yawOf(R), 2.5, 1e-12);
}

TEST(SensorInputs, AttitudeIsTheNearestSampleWithinTheTolerance) {
  SensorInputsParams p;
  p.imu_max_time_difference = 0.05;
  SensorInputs in(p);
  // Out of order on purpose: kept in stamp order.
  EXPECT_TRUE(in.addOrientation(10.10, rpy(0.0, 0.0, 0.2)));
  EXPECT_TRUE(in.addOrientation(10.00, rpy(0.01, 0.02, 0.1)));
  EXPECT_TRUE(in.addOrientation(10.20, rpy(0.0, 0.0, 0.3)));
  EXPECT_FALSE(in.addOrientation(10.30, Eigen::Quaterniond(0, 0, 0, 0)));
  EXPECT_FALSE(in.addOrientation(10.30, Eigen::Quaterniond(NAN, 0, 0, 1)));
  EXPECT_EQ(in.numAttitudes(), 3u);
  const auto a = in.attitudeAt(10.02);
  ASSERT_TRUE(a);
  EXPECT_NEAR(a->yaw, 0.1, 1e-12);
  EXPECT_NEAR(a->roll, 0.01, 1e-12);
  EXPECT_NEAR(a->pitch, 0.02, 1e-12);
  EXPECT_NEAR(in.attitudeAt(10.09)->yaw, 0.2, 1e-12);
  EXPECT_NEAR(in.attitudeAt(10.15)->yaw, 0.3, 1e-12);  // a tie: the later sample
  EXPECT_FALSE(in.attitudeAt(9.90));                   // 0.1 s before the first
  EXPECT_FALSE(in.attitudeAt(10.30));
  EXPECT_NEAR(in.firstAttitude()->yaw, 0.1, 1e-12);
}

TEST(SensorInputs, TheFirstHeadingFallsBackToTheNewestRecentSampleAndSaysSo) {
  SensorInputsParams p;
  p.imu_max_time_difference = 0.05;
  p.initial_heading_max_age = 1.0;
  SensorInputs none(p);
  EXPECT_FALSE(none.initialHeading(5.0).yaw);
  EXPECT_TRUE(none.initialHeading(5.0).warning.empty());  // no IMU at all: nothing to say

  SensorInputs in(p);
  in.addOrientation(4.0, rpy(0, 0, 0.4));
  in.addOrientation(4.6, rpy(0, 0, 0.6));
  in.addOrientation(7.0, rpy(0, 0, 0.9));  // after the keyframe: never its heading
  const InitialHeading at = in.initialHeading(4.62);
  ASSERT_TRUE(at.yaw);
  EXPECT_NEAR(*at.yaw, 0.6, 1e-12);
  EXPECT_TRUE(at.warning.empty());
  const InitialHeading late = in.initialHeading(5.3);  // the first scans were lost
  ASSERT_TRUE(late.yaw);
  EXPECT_NEAR(*late.yaw, 0.6, 1e-12);
  EXPECT_NE(late.warning.find("0.7"), std::string::npos) << late.warning;
  const InitialHeading stale = in.initialHeading(6.0);
  EXPECT_FALSE(stale.yaw);
  EXPECT_NE(stale.warning.find("no initial heading"), std::string::npos) << stale.warning;
}

TEST(SensorInputs, GnssPositionsNeedTheOriginAndFollowTheFixes) {
  SensorInputsParams p;
  p.gnss_max_gap = 1.5;
  p.gnss_max_time_difference = 0.05;
  SensorInputs in(p);
  const double lat = 49.0, lon = 8.4;
  const EnuConverter enu(lat, lon, 0.0);
  const Eigen::Vector3d a = enu.toGeodetic(Eigen::Vector3d(10.0, 0.0, 0.0));
  const Eigen::Vector3d b = enu.toGeodetic(Eigen::Vector3d(20.0, 4.0, 0.0));
  EXPECT_TRUE(in.addFix({2.0, b.x(), b.y(), 0.0, 0.8}));
  EXPECT_TRUE(in.addFix({1.0, a.x(), a.y(), 0.0, 0.8}));
  EXPECT_FALSE(in.addFix({3.0, NAN, lon, 0.0, 0.8}));
  EXPECT_EQ(in.numFixes(), 2u);
  EXPECT_FALSE(in.gnssPositionAt(1.5));  // no origin yet
  in.setOrigin(lat, lon);
  const auto mid = in.gnssPositionAt(1.5);
  ASSERT_TRUE(mid);
  EXPECT_NEAR(mid->xy.x(), 15.0, 1e-3);
  EXPECT_NEAR(mid->xy.y(), 2.0, 1e-3);
  EXPECT_DOUBLE_EQ(mid->std_xy, 0.8);
  EXPECT_FALSE(in.gnssPositionAt(2.2));  // beyond the last fix by more than the tolerance
  in.stopKeepingFixes();
  EXPECT_EQ(in.numFixes(), 0u);
  EXPECT_TRUE(in.addFix({4.0, a.x(), a.y(), 0.0, 0.8}));  // valid, but not kept
  EXPECT_EQ(in.numFixes(), 0u);
}

TEST(SensorInputs, KeepsAtMostMaxSamplesUnlessUnbounded) {
  SensorInputsParams p;
  p.max_samples = 3;
  SensorInputs bounded(p);
  p.max_samples = 0;
  SensorInputs all(p);
  for (int i = 0; i < 10; ++i) {
    bounded.addOrientation(i, rpy(0, 0, 0.1 * i));
    all.addOrientation(i, rpy(0, 0, 0.1 * i));
  }
  EXPECT_EQ(bounded.numAttitudes(), 3u);
  EXPECT_NEAR(bounded.firstAttitude()->stamp, 7.0, 1e-12);  // the oldest went first
  EXPECT_EQ(all.numAttitudes(), 10u);
}

// The localiser's IMU per scan: the mean of the readings between two scans; without one in the
// interval the nearest within the gap; readings out of order are put in place.
TEST(ImuReadingBuffer, MeanBetweenScansAndNearestWithinTheGap) {
  ImuReadingBuffer buffer;  // stamps in eighths of a second: exact in binary
  for (int i = 0; i < 10; ++i) buffer.add(0.125 * i, Eigen::Vector3d(i, 0.0, 0.0));
  buffer.add(0.5625, Eigen::Vector3d(100.0, 0.0, 0.0));      // out of order
  buffer.add(2.0, Eigen::Vector3d(std::nan(""), 0.0, 0.0));  // ignored
  EXPECT_EQ(buffer.size(), 11u);
  EXPECT_NEAR(buffer.meanBetween(0.25, 0.5, 0.1)->x(), 3.5, 1e-12);    // 3, 4
  EXPECT_NEAR(buffer.meanBetween(0.5, 0.625, 0.1)->x(), 52.5, 1e-12);  // 100, 5
  EXPECT_NEAR(buffer.meanBetween(1.25, 1.5, 0.5)->x(), 9.0, 1e-12);    // nearest: 9 at 1.125
  EXPECT_FALSE(buffer.meanBetween(1.25, 1.5, 0.3));
  EXPECT_FALSE(ImuReadingBuffer().meanBetween(0.0, 1.0, 1.0));
  ImuReadingBuffer live(1.0);  // live use keeps the last second only
  for (int i = 0; i <= 32; ++i) live.add(0.125 * i, Eigen::Vector3d::Constant(i));
  EXPECT_EQ(live.size(), 9u);
}

}  // namespace
}  // namespace osm_graph_slam
