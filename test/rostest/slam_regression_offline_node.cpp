// Rostest node for slam_regression_offline.test (issue 9): offline_slam on the shared ~60 s
// simulated drive (slam_regression_common.h) with the perturbed prior and with --no-osm, and the
// issue's targets on the result: ATE with OSM <= ate_ratio_max x ATE without; RPE with <=
// rpe_ratio_max x RPE without; mean building corner error after <= building_ratio_max x before;
// no overlapping buildings; every output file parses. Thresholds are ~parameters of the .test.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include "slam_regression_common.h"

namespace osm_graph_slam {
namespace {

using namespace regression;

struct Runs {
  Drive drive;
  fs::path with_osm, without_osm;
  int with_rc = -1, without_rc = -1;
  double with_s = 0, without_s = 0;
};
Runs* R = nullptr;

class SlamRegressionOffline : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    R = new Runs;
    ros::NodeHandle pnh("~");
    R->drive = prepareDrive(driveOptionsFromParams(pnh));
    if (!R->drive.error.empty()) return;
    // The last run's outputs stay in the cache for inspection (overwritten by the next run).
    const fs::path out = R->drive.dir / "runs" / "offline";
    R->with_osm = out / "with_osm";
    R->without_osm = out / "without_osm";
    R->with_rc =
        runOfflineSlam(R->drive, R->with_osm, "--osm '" + R->drive.prior_osm + "'", &R->with_s);
    R->without_rc = runOfflineSlam(R->drive, R->without_osm, "--no-osm", &R->without_s);
    for (const auto& [dir, s] : {std::pair{R->with_osm, R->with_s}, {R->without_osm, R->without_s}})
      std::cout << "[slam_regression] " << dir << " (" << s << " s):\n"
                << readText(dir / "timing.txt") << std::flush;
  }
  static void TearDownTestSuite() {
    delete R;
    R = nullptr;
  }
  void SetUp() override {
    ASSERT_TRUE(R->drive.error.empty()) << R->drive.error;
    ASSERT_EQ(R->with_rc, 0) << readText(R->with_osm.string() + ".log");
    ASSERT_EQ(R->without_rc, 0) << readText(R->without_osm.string() + ".log");
  }
};

TEST_F(SlamRegressionOffline, OutputFilesParse) {
  const size_t with = expectSaveMapOutputsParse(R->with_osm, true, true);
  const size_t without = expectSaveMapOutputsParse(R->without_osm, false, true);
  // The front-end is the same with and without OSM: the same keyframes.
  EXPECT_EQ(with, without);
}

TEST_F(SlamRegressionOffline, OsmPriorsMeetTheTargets) {
  RunMetrics m;
  std::string error;
  ASSERT_TRUE(evaluateRun(R->drive, R->with_osm, R->without_osm, m, &error)) << error;
  printMetrics("offline_slam on " + R->drive.world, m);
  EXPECT_GE(m.slam.associated, 20u);
  EXPECT_EQ(m.slam.associated, m.baseline.associated);
  EXPECT_LE(m.slam.ate.mean, param("ate_ratio_max", 0.7) * m.baseline.ate.mean)
      << "ATE with OSM " << m.slam.ate.mean << " m, without " << m.baseline.ate.mean << " m";
  EXPECT_LE(m.slam.ate.mean, param("ate_max_m", 1e9)) << "ATE with OSM";
  const TrajectoryErrors& base = m.baseline_same_steps;
  EXPECT_LE(m.slam.rpe_trans.mean, param("rpe_ratio_max", 1.05) * base.rpe_trans.mean)
      << "RPE with OSM " << m.slam.rpe_trans.mean << " m, without " << base.rpe_trans.mean;
  EXPECT_LE(m.slam.rpe_rot.mean, param("rpe_rot_ratio_max", 1.05) * base.rpe_rot.mean)
      << "rotational RPE with OSM " << m.slam.rpe_rot.mean << " rad, without " << base.rpe_rot.mean;
  EXPECT_GE(m.after.matched, 5u) << "fewer than 5 buildings observed (robot<->building edges)";
  EXPECT_LE(m.after.mean_corner_error,
            param("building_ratio_max", 0.5) * m.before.mean_corner_error)
      << "building corner error before " << m.before.mean_corner_error << " m, after "
      << m.after.mean_corner_error << " m";
  EXPECT_LE(double(m.overlapping_pairs), param("max_overlapping_pairs", 0.0));
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "slam_regression_offline");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
