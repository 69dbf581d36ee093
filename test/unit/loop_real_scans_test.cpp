// Loop verification on real HDL-64E scans (../shared/data/patchwork, KITTI): frame 5 against
// frame 0 (~3.7 m apart) must verify with the pose of a direct well-converged registration; a
// KITTI 00 scan of another place must be rejected, in place-recognition mode (coarse GICP) and
// in odometry mode (correlative search over the odometry tolerance window).
#include <gtest/gtest.h>

#include <iostream>

#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

PointCloudPtr load(const std::string& relative) {
  auto cloud = std::make_shared<PointCloud>();
  std::string error;
  EXPECT_TRUE(readKittiBin(test::sharedDataPath(relative), *cloud, &error)) << error;
  return cloud;
}

LoopKeyframe keyframe(uint64_t id, const PointCloudPtr& cloud, double accum) {
  LoopKeyframe kf;
  kf.id = id;
  kf.cloud = cloud;
  kf.accum_distance = accum;  // odometry pose left at identity: no odometry information
  return kf;
}

/// Reference: GICP frame-to-frame chain 0->1->...->5 on 0.2 m voxels, composed.
Eigen::Isometry3d chainedReference(const std::vector<PointCloudPtr>& scans) {
  RegistrationParams p;
  p.max_iterations = 100;
  p.transformation_epsilon = 1e-6;
  p.method = "pcl_gicp";  // independent back-end as reference
  auto reg = createRegistration(p);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // scan k in frame 0
  for (size_t k = 1; k < scans.size(); ++k) {
    reg->setTarget(downsampleForLoop(*scans[k - 1], 0.2));
    Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
    guess.translation().x() = 0.74;
    const auto r = reg->align(downsampleForLoop(*scans[k], 0.2), guess);
    EXPECT_TRUE(r.converged);
    pose = pose * r.transform;
  }
  return pose;
}

TEST(LoopRealScans, CorrelativeStageClosesFrame5WithDriftedOdometry) {
  for (int i = 0; i <= 5; ++i) {
    OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("patchwork/00000" + std::to_string(i) + ".bin"));
  }
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000094.bin"));
  std::vector<PointCloudPtr> scans;
  for (int i = 0; i <= 5; ++i)
    scans.push_back(load("patchwork/00000" + std::to_string(i) + ".bin"));
  const Eigen::Isometry3d reference = chainedReference(scans);
  // The default, and the fine stage on every query point (fine_max_source_points 0, the old).
  for (const int max_source : {LoopDetectorParams().fine_max_source_points, 0}) {
    SCOPED_TRACE("fine_max_source_points " + std::to_string(max_source));
    LoopDetectorParams params;  // default: correlative coarse stage
    params.min_accum_distance_gap = 0.0;
    params.fine_max_source_points = max_source;
    LoopDetector detector(params);
    ASSERT_TRUE(detector.addKeyframe(keyframe(0, scans[0], 0.0)));
    // Back after 200 m (tolerance 4 m, 0.09 rad) with odometry 1.5 m / 0.8 m / 0.04 rad off.
    LoopKeyframe query = keyframe(5, scans[5], 200.0);
    query.odom_pose = reference;
    query.odom_pose.translation() += Eigen::Vector3d(1.5, -0.8, 0.0);
    query.odom_pose.linear() =
        Eigen::AngleAxisd(0.04, Eigen::Vector3d::UnitZ()).matrix() * reference.linear();
    const auto loop = detector.detect(query);
    ASSERT_TRUE(loop.has_value()) << detector.lastStats().reason;
    const auto& outcome = detector.lastStats().outcomes.back();
    const Eigen::Isometry3d delta = reference.inverse() * loop->relative_pose;
    const double dt = delta.translation().norm();
    const double dr = Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI;
    std::cout << "[ loop_real ] correlative 5->0 (fine_max_source_points " << max_source
              << "): diff " << dt << " m " << dr << " deg, BEV score " << outcome.bev_score
              << ", ambiguity " << outcome.ambiguity << ", fitness " << loop->fitness
              << ", overlap " << loop->overlap << "\n";
    EXPECT_LT(dt, 0.10);
    EXPECT_LT(dr, 0.5);
    EXPECT_LT(outcome.ambiguity, params.max_ambiguity);
    EXPECT_GT(outcome.bev_score, 0.5);

    // The unrelated KITTI scan claiming, by odometry, to be at frame 0: never accepted.
    LoopKeyframe wrong_query = keyframe(6, load("kitti00/000094.bin"), 200.0);
    const auto wrong = detector.detect(wrong_query);
    std::cout << "[ loop_real ] correlative, unrelated scan: " << (wrong ? "ACCEPTED" : "rejected")
              << " (" << detector.lastStats().reason << ")\n";
    for (const auto& o : detector.lastStats().outcomes) {
      std::cout << "   candidate " << o.id << " BEV score " << o.bev_score << " ambiguity "
                << o.ambiguity << " fitness " << o.fitness << " overlap " << o.overlap << " -> "
                << o.verdict << "\n";
    }
    EXPECT_FALSE(wrong.has_value());
  }
}

TEST(LoopRealScans, Frame5ClosesOnFrame0AndUnrelatedScanIsRejected) {
  for (int i = 0; i <= 5; ++i) {
    OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("patchwork/00000" + std::to_string(i) + ".bin"));
  }
  OGS_REQUIRE_SHARED_FILE(test::sharedDataPath("kitti00/000094.bin"));
  std::vector<PointCloudPtr> scans;
  for (int i = 0; i <= 5; ++i)
    scans.push_back(load("patchwork/00000" + std::to_string(i) + ".bin"));
  const PointCloudPtr unrelated = load("kitti00/000094.bin");

  LoopDetectorParams params;
  params.min_accum_distance_gap = 0.0;  // six consecutive frames: allow the short "loop"
  params.check_odometry_consistency = false;
  LoopDetector detector(params);
  ASSERT_TRUE(detector.addKeyframe(keyframe(0, scans[0], 0.0)));

  auto loop = detector.relocalize(keyframe(5, scans[5], -1.0));
  ASSERT_TRUE(loop.has_value()) << detector.lastStats().reason;
  EXPECT_EQ(loop->to_id, 0u);
  const Eigen::Isometry3d reference = chainedReference(scans);
  const Eigen::Isometry3d delta = reference.inverse() * loop->relative_pose;
  const double dt = delta.translation().norm();
  const double dr = Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI;
  std::cout << "[ loop_real ] 5->0: t = " << loop->relative_pose.translation().transpose()
            << " (reference " << reference.translation().transpose() << "), diff " << dt << " m "
            << dr << " deg, fitness " << loop->fitness << ", overlap " << loop->overlap
            << ", descriptor " << loop->descriptor_distance << "\n";
  // Five frames of ~0.74 m forward motion.
  EXPECT_NEAR(loop->relative_pose.translation().norm(), 5 * 0.74, 0.3);
  EXPECT_LT(dt, 0.10);
  EXPECT_LT(dr, 0.5);
  EXPECT_LE(loop->fitness, params.max_fitness);
  EXPECT_GT(loop->information(0, 0), 1.0);

  // Unrelated place: rejected by the descriptor or by verification, never accepted.
  const auto wrong = detector.relocalize(keyframe(6, unrelated, -1.0));
  std::cout << "[ loop_real ] unrelated scan: " << (wrong ? "ACCEPTED" : "rejected") << " ("
            << detector.lastStats().reason << ")\n";
  for (const auto& o : detector.lastStats().outcomes) {
    std::cout << "   candidate " << o.id << " descriptor " << o.descriptor_distance << " fitness "
              << o.fitness << " overlap " << o.overlap << " -> " << o.verdict << "\n";
  }
  EXPECT_FALSE(wrong.has_value());
}

TEST(LoopRealScans, BadInputIsRejectedWithoutCrash) {
  LoopDetector detector((LoopDetectorParams()));
  EXPECT_FALSE(detector.addKeyframe(LoopKeyframe()));  // null cloud
  auto empty = std::make_shared<PointCloud>();
  EXPECT_FALSE(detector.addKeyframe(keyframe(1, empty, 0.0)));
  auto nan_cloud = std::make_shared<PointCloud>();
  PointT nan_point;
  nan_point.x = nan_point.y = nan_point.z = std::numeric_limits<float>::quiet_NaN();
  nan_cloud->resize(1000, nan_point);
  EXPECT_FALSE(detector.addKeyframe(keyframe(2, nan_cloud, 0.0)));
  EXPECT_EQ(detector.size(), 0u);
  EXPECT_FALSE(detector.process(keyframe(3, empty, 10.0)).has_value());
  EXPECT_FALSE(detector.relocalize(keyframe(4, nan_cloud, -1.0)).has_value());
}

}  // namespace
}  // namespace osm_graph_slam
