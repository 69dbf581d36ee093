// KeyframeTracker: odometry over six real consecutive scans against the direct registration,
// keyframe policy, failure handling (prediction kept) and rejected input.
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>

#include "frontend_test_utils.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "osm_graph_slam/odometry/tracking_health.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

using test::rotationErrorDeg;
using test::translationError;

std::string patchworkScan(int i) {
  char name[64];
  std::snprintf(name, sizeof(name), "patchwork/%06d.bin", i);
  return test::sharedDataPath(name);
}

std::vector<PointCloudPtr> loadPatchwork() {
  std::vector<PointCloudPtr> scans;
  for (int i = 0; i < 6; ++i) scans.push_back(test::loadFilteredScan(patchworkScan(i)));
  return scans;
}

/// For the synthetic scene's instantaneous scans (no sweep to undo), one keyframe for the test.
KeyframeTrackerParams syntheticSceneParams() {
  KeyframeTrackerParams params;
  params.deskew = false;
  params.keyframe_delta_trans = 100.0;
  params.keyframe_delta_time = 100.0;
  return params;
}

TEST(KeyframeTrackerTest, OdometryAgreesWithDirectRegistrationOverSixScans) {
  OGS_REQUIRE_SHARED_FILE(patchworkScan(5));
  const auto scans = loadPatchwork();
  KeyframeTrackerParams params;
  KeyframeTracker tracker(params);
  std::vector<uint64_t> keyframe_ids;
  TrackResult last;
  for (int i = 0; i < 6; ++i) {
    last = tracker.track(0.1 * i, scans[i]);
    ASSERT_FALSE(last.failed()) << "scan " << i << ": " << last.message;
    keyframe_ids.push_back(last.keyframe_id);
    std::cout << "[patchwork] scan " << i << " keyframe " << last.keyframe_id
              << (last.new_keyframe ? " (new)" : "")
              << " t = " << last.pose.translation().transpose() << " fitness "
              << last.registration.fitness << " iterations " << last.registration.iterations
              << "\n";
  }
  // ~0.74 m per scan: keyframes 0 (scan 0) and 1 (scan 3, 2.2 m > 2 m); scan 5 matches keyframe 1.
  EXPECT_EQ(tracker.keyframeCount(), 2u);
  EXPECT_EQ(keyframe_ids, (std::vector<uint64_t>{0, 0, 0, 1, 1, 1}));
  EXPECT_NEAR(tracker.keyframe().accum_distance, 2.2, 0.3);

  // Direct 0 -> 5 registration, independent of the odometry: 3.7 m is beyond the default 1 m
  // correspondence distance, so a coarse pass (5 m) from identity, then the default settings.
  RegistrationParams coarse_params;
  coarse_params.max_correspondence_distance = 5.0;
  auto coarse_reg = createRegistration(coarse_params);
  coarse_reg->setTarget(scans[0]);
  const auto coarse = coarse_reg->align(scans[5], Eigen::Isometry3d::Identity());
  ASSERT_TRUE(coarse.converged) << coarse.message;
  auto direct_reg = createRegistration(RegistrationParams());
  direct_reg->setTarget(scans[0]);
  const auto direct = direct_reg->align(scans[5], coarse.transform);
  ASSERT_TRUE(direct.converged) << direct.message;
  const double et = translationError(direct.transform, last.pose);
  const double er = rotationErrorDeg(direct.transform, last.pose);
  std::cout << "[patchwork 0->5] direct |t| = " << direct.transform.translation().norm()
            << " m; odometry vs direct: " << et * 100 << " cm, " << er << " deg\n";
  EXPECT_GT(direct.transform.translation().norm(), 3.0);  // a real motion, not identity
  EXPECT_LT(et, 0.05);
  EXPECT_LT(er, 0.2);
}

TEST(KeyframeTrackerTest, FailedMatchKeepsConstantVelocityPrediction) {
  const auto scene = test::syntheticScene(600);
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.translation() << 0.5, 0.05, 0.0;
  step.linear() = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  // The scene seen from poses 0, step, step^2: a cloud seen from pose T is T^-1 * scene.
  KeyframeTracker tracker(syntheticSceneParams());
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 3; ++i) {
    const auto result = tracker.track(1.0 + i, test::transformed(*scene, pose.inverse()));
    ASSERT_FALSE(result.failed()) << result.message;
    EXPECT_LT(translationError(pose, result.pose), 1e-3) << "scan " << i;
    pose = pose * step;
  }
  // Scan 3 sees something unmatchable (a far-away blob): the match must fail and the pose must be
  // the constant-velocity prediction.
  PointCloudPtr garbage = std::make_shared<PointCloud>();
  for (int i = 0; i < 200; ++i) {
    PointT p;
    p.x = 500.0f + 0.01f * i;
    p.y = 500.0f;
    p.z = 0.0f;
    garbage->push_back(p);
  }
  const auto failed = tracker.track(4.0, garbage);
  EXPECT_TRUE(failed.failed());
  EXPECT_EQ(failed.status, TrackStatus::kMatchFailed);
  EXPECT_FALSE(failed.message.empty());
  EXPECT_FALSE(failed.new_keyframe);
  EXPECT_LT(translationError(pose, failed.pose), 1e-3);
  EXPECT_LT(rotationErrorDeg(pose, failed.pose), 1e-3);
  pose = pose * step;
  // Tracking resumes on the next good scan.
  const auto resumed = tracker.track(5.0, test::transformed(*scene, pose.inverse()));
  EXPECT_EQ(resumed.status, TrackStatus::kMatched) << resumed.message;
  EXPECT_LT(translationError(pose, resumed.pose), 1e-3);
}

// The back-end trusts a match's geometry less when the motion model missed the motion (the scan
// was deskewed by the wrong motion): the tracker reports how far the match lies from it.
TEST(KeyframeTrackerTest, PredictionErrorIsHowFarTheMatchLiesFromTheMotionModel) {
  const auto scene = test::syntheticScene(600);
  KeyframeTracker tracker(syntheticSceneParams());
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d step(0.5, 0.02, 0.0);
  for (int i = 0; i < 4; ++i) {
    const auto result = tracker.track(0.1 * i, test::transformed(*scene, pose.inverse()));
    ASSERT_FALSE(result.failed()) << result.message;
    if (i >= 2) {
      EXPECT_LT(result.prediction_error.norm(), 1e-3) << "constant velocity, scan " << i;
    }
    pose.translation() += step;
  }
  pose.translation().x() += 0.3;  // the vehicle lurches: 0.3 m the model could not know
  const auto lurch = tracker.track(0.4, test::transformed(*scene, pose.inverse()));
  ASSERT_EQ(lurch.status, TrackStatus::kMatched) << lurch.message;
  EXPECT_NEAR(lurch.prediction_error.x(), 0.3, 0.005);  // in base_link: ahead
  EXPECT_NEAR(lurch.prediction_error.tail<2>().norm(), 0.0, 0.005);
}

TEST(KeyframeTrackerTest, NewKeyframeWhenTimeOrAngleThresholdExceeded) {
  const auto scene = test::syntheticScene(600);
  KeyframeTrackerParams params;
  params.deskew = false;  // the synthetic scans are instantaneous: no sweep to undo
  params.keyframe_delta_trans = 100.0;
  params.keyframe_delta_angle = 0.1;
  params.keyframe_delta_time = 2.5;
  KeyframeTracker tracker(params);
  EXPECT_TRUE(tracker.track(0.0, scene).new_keyframe);
  EXPECT_FALSE(tracker.track(1.0, scene).new_keyframe);
  EXPECT_TRUE(tracker.track(3.0, scene).new_keyframe);  // 3 s after keyframe 0
  Eigen::Isometry3d turned = Eigen::Isometry3d::Identity();
  turned.linear() = Eigen::AngleAxisd(0.12, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto result = tracker.track(3.5, test::transformed(*scene, turned.inverse()));
  EXPECT_EQ(result.status, TrackStatus::kMatched) << result.message;
  EXPECT_TRUE(result.new_keyframe);
  EXPECT_EQ(tracker.keyframeCount(), 3u);
}

TEST(KeyframeTrackerTest, RejectsOutOfOrderStampsAndBadCloudsWithoutStateChange) {
  const auto scene = test::syntheticScene(600);
  KeyframeTracker tracker;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointCloudPtr nan_only = std::make_shared<PointCloud>();
  PointT bad;
  bad.x = bad.y = bad.z = nan;
  for (int i = 0; i < 100; ++i) nan_only->push_back(bad);
  PointCloudPtr single = std::make_shared<PointCloud>();
  single->push_back(scene->points[0]);
  // Bad clouds before the first keyframe: nothing initialised.
  for (const auto& cloud : {std::make_shared<PointCloud>(), single, PointCloudPtr()}) {
    TrackResult r;
    ASSERT_NO_THROW(r = tracker.track(1.0, cloud));
    EXPECT_EQ(r.status, TrackStatus::kRejectedCloud);
    EXPECT_FALSE(r.message.empty());
    EXPECT_FALSE(tracker.initialized());
  }
  ASSERT_EQ(tracker.track(1.0, scene).status, TrackStatus::kFirstKeyframe);
  // Same or older stamps: rejected with a reason, pose and keyframe untouched.
  for (const double stamp : {1.0, 0.5, std::numeric_limits<double>::quiet_NaN()}) {
    const auto r = tracker.track(stamp, scene);
    EXPECT_EQ(r.status, TrackStatus::kRejectedStamp);
    EXPECT_FALSE(r.message.empty());
  }
  // A NaN-only cloud with enough points gets to the registration, which fails cleanly.
  TrackResult r;
  ASSERT_NO_THROW(r = tracker.track(2.0, nan_only));
  EXPECT_EQ(r.status, TrackStatus::kMatchFailed);
  EXPECT_TRUE(r.pose.matrix().allFinite());
  EXPECT_LT(r.pose.translation().norm(), 1e-9);
  EXPECT_EQ(tracker.keyframeCount(), 1u);
}

TEST(KeyframeTrackerTest, JumpBackInTimeRestartsTrackingSmallStepsBackAreRejected) {
  OGS_REQUIRE_SHARED_FILE(patchworkScan(5));
  const auto scans = loadPatchwork();
  KeyframeTrackerParams params;
  params.restart_after_jump_back = 5.0;
  KeyframeTracker tracker(params);
  TrackingHealth health(params.lost_track_after);
  for (int i = 0; i < 6; ++i) {
    const TrackResult r = tracker.track(110.0 + 0.1 * i, scans[i]);
    health.update(110.0 + 0.1 * i, r);
    ASSERT_FALSE(r.failed()) << r.message;
  }
  const Eigen::Isometry3d before = tracker.pose();
  const uint64_t last_id = tracker.keyframe().id;
  const double accum = tracker.keyframe().accum_distance;
  // A duplicated stamp and one 4 s back (below the limit): each rejected, nothing changed.
  for (const double stamp : {110.5, 106.5}) {
    const TrackResult r = tracker.track(stamp, scans[5]);
    EXPECT_FALSE(health.update(stamp, r));
    EXPECT_EQ(r.status, TrackStatus::kRejectedStamp) << stamp;
    EXPECT_EQ(tracker.keyframe().id, last_id);
  }
  // The time 10.5 s back (a bag looped to its start): one restart, ids and pose continue.
  const TrackResult restart = tracker.track(100.0, scans[0]);
  ASSERT_EQ(restart.status, TrackStatus::kRestarted) << restart.message;
  EXPECT_TRUE(restart.new_keyframe);
  EXPECT_TRUE(restart.reanchored);  // the back-end links it weakly
  EXPECT_EQ(restart.keyframe_id, last_id + 1);
  EXPECT_NE(restart.message.find("time jumped back"), std::string::npos) << restart.message;
  EXPECT_LT(translationError(restart.pose, before), 1e-9);
  EXPECT_GE(tracker.keyframe().accum_distance, accum);
  const auto event = health.update(100.0, restart);
  ASSERT_TRUE(event);
  EXPECT_NE(event->message.find("restart"), std::string::npos) << event->message;
  EXPECT_EQ(health.stats().restarts, 1u);
  // The second pass tracks again from there, with the same motion as the first.
  for (int i = 1; i < 6; ++i) {
    const TrackResult r = tracker.track(100.0 + 0.1 * i, scans[i]);
    EXPECT_FALSE(health.update(100.0 + 0.1 * i, r));
    ASSERT_EQ(r.status, TrackStatus::kMatched) << "scan " << i << ": " << r.message;
  }
  EXPECT_NEAR((before.inverse() * tracker.pose()).translation().norm(), before.translation().norm(),
              0.1);
  EXPECT_EQ(health.stats().restarts, 1u);
  EXPECT_EQ(health.stats().rejected_scans, 2u);
  // The time since a keyframe runs from the restart, the drive's last stamp stays the latest.
  EXPECT_LT(health.timeSinceKeyframe(), 1.0);
  EXPECT_DOUBLE_EQ(health.stats().last_stamp, 110.5);
}

TEST(KeyframeTrackerTest, RestartAfterJumpBackCanBeDisabled) {
  OGS_REQUIRE_SHARED_FILE(patchworkScan(1));
  const auto scans = loadPatchwork();
  KeyframeTrackerParams params;
  params.restart_after_jump_back = 0.0;
  KeyframeTracker tracker(params);
  ASSERT_EQ(tracker.track(100.0, scans[0]).status, TrackStatus::kFirstKeyframe);
  EXPECT_EQ(tracker.track(10.0, scans[1]).status, TrackStatus::kRejectedStamp);
}

}  // namespace
}  // namespace osm_graph_slam
