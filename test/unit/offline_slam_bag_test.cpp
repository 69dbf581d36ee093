// offline_slam --bag against --kitti-raw: a short simulated drive (procedural city, generated in
// a temp dir) is converted with the kitti2bag library and run both ways through the
// offline_slam executable; the trajectories, ground truth and buildings must agree. Also the
// bag reader itself (static TF chain, IMU attitude, nearest-stamp look-ups) and bad input.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/sim/simulator.h"
#include "osm_graph_slam/slam/sensor_inputs.h"
#include "test_data.h"

namespace fs = std::filesystem;

namespace osm_graph_slam {
namespace {

constexpr int kScans = 60;  // 6 s at 10 Hz: ~15 keyframes, enough for OSM matching to start

/// The drive, generated once for all tests of this file.
struct Drive {
  fs::path dir, drive_dir, bag, prior_osm;
  std::string error;
};
Drive* D = nullptr;

std::string toolPath(const std::string& name) {
  // Tools and test binaries share build_ws/devel/lib/osm_graph_slam.
  return (fs::read_symlink("/proc/self/exe").parent_path() / name).string();
}

/// Runs a command; returns its exit code and its stdout+stderr in *output.
int run(const std::string& command, std::string* output) {
  const std::string log = (D->dir / "command.log").string();
  const int status = std::system((command + " > '" + log + "' 2>&1").c_str());
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  if (output) *output = ss.str();
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string offlineSlam(const std::string& input, const fs::path& out,
                        const std::string& extra = "") {
  return "'" + toolPath("offline_slam") + "' " + input + " --output '" + out.string() +
         "' --osm '" + D->prior_osm.string() + "' --config '" + test::sourceDir() +
         "/config/sim.yaml' " + extra;
}

class OfflineSlamBag : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    D = new Drive;
    D->dir = fs::temp_directory_path() / ("ogs_offline_bag_" + std::to_string(::getpid()));
    fs::create_directories(D->dir);
    sim::SimulationParams params;
    params.route.length = 400.0;
    params.max_scans = kScans;
    params.motion_distortion = true;
    sim::UrbanSimulator simulator;
    sim::SimulationStats stats;
    if (!simulator.build(params, &D->error) ||
        !simulator.writeDataset((D->dir / "sim").string(), stats, {}, &D->error))
      return;
    D->drive_dir = stats.drive_dir;
    D->prior_osm = D->dir / "sim" / "prior.osm";
    KittiRawBagOptions bag;
    bag.drive_dir = D->drive_dir.string();
    bag.bag_path = (D->dir / "drive.bag").string();
    const BagConversionResult r = convertKittiRawToBag(bag);
    if (!r.ok) D->error = "kitti2bag: " + r.error;
    D->bag = bag.bag_path;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(D->dir, ec);
    delete D;
    D = nullptr;
  }
  void SetUp() override { ASSERT_TRUE(D->error.empty()) << D->error; }
};

TEST_F(OfflineSlamBag, ReaderGivesTheDrivesFramesAttitudeAndTruth) {
  BagDriveReader reader;
  std::string error;
  ASSERT_TRUE(reader.open(D->bag.string(), {}, &error)) << error;
  EXPECT_EQ(reader.numClouds(), size_t(kScans));
  EXPECT_EQ(reader.numImu(), size_t(kScans));
  EXPECT_EQ(reader.numGroundTruth(), size_t(kScans));

  KittiRawDrive drive;
  ASSERT_TRUE(openKittiRawDrive(D->drive_dir.string(), "", drive, &error)) << error;
  const auto base_T_velo = reader.baseToFrame("velo_link");
  ASSERT_TRUE(base_T_velo);
  EXPECT_TRUE(base_T_velo->isApprox(drive.T_velo_imu.inverse(), 1e-9));
  EXPECT_TRUE(reader.baseToFrame("base_link")->isApprox(Eigen::Isometry3d::Identity()));
  // velo_link -> imu_link through base_link (both directions of the static tree).
  EXPECT_TRUE(reader.baseToFrame("imu_link"));
  EXPECT_FALSE(reader.baseToFrame("camera_link"));

  OxtsRecord first;
  ASSERT_TRUE(readOxtsFile(drive.oxts_files.front(), first, &error)) << error;
  const auto fix = reader.firstFix();
  ASSERT_TRUE(fix);
  EXPECT_DOUBLE_EQ(fix->lat, first.lat);
  EXPECT_DOUBLE_EQ(fix->lon, first.lon);
  // The bag's IMU and fixes, matched by time as the offline runner and the nodelet do.
  SensorInputsParams params;
  params.max_samples = 0;
  SensorInputs inputs(params);
  for (const BagFix& f : reader.fixes())
    inputs.addFix({static_cast<double>(f.stamp_ns) * 1e-9, f.lat, f.lon, f.alt, f.std_xy});
  for (const auto& [stamp_ns, q] : reader.orientations())
    inputs.addOrientation(static_cast<double>(stamp_ns) * 1e-9, q);
  const auto a = inputs.firstAttitude();
  ASSERT_TRUE(a);
  EXPECT_NEAR(a->yaw, first.yaw, 1e-12);
  EXPECT_NEAR(a->roll, first.roll, 1e-12);
  EXPECT_NEAR(a->pitch, first.pitch, 1e-12);
  const auto seconds = [](int64_t ns) { return static_cast<double>(ns) * 1e-9; };
  // Body rates and specific force in base_link (the IMU is base_link in KITTI), as OXTS gave them.
  const std::vector<BagImuReading> gyro = reader.imuRates(false), accel = reader.imuRates(true);
  ASSERT_EQ(gyro.size(), size_t(kScans));
  ASSERT_EQ(accel.size(), size_t(kScans));
  EXPECT_LT((gyro.front().value - Eigen::Vector3d(first.wx, first.wy, first.wz)).norm(), 1e-9);
  EXPECT_LT((accel.front().value - Eigen::Vector3d(first.ax, first.ay, first.az)).norm(), 1e-9);
  EXPECT_GT(accel.front().value.z(), 9.0) << "gravity is in the specific force";

  // Clouds in stamp order, bit-exact copies of the .bin scans, with IMU and truth at each stamp.
  size_t n = 0;
  while (auto c = reader.nextCloud()) {
    ASSERT_TRUE(c->cloud) << c->error;
    EXPECT_EQ(c->stamp_ns, drive.scan_stamps[n]);
    EXPECT_EQ(c->frame_id, "velo_link");
    EXPECT_TRUE(inputs.attitudeAt(seconds(c->stamp_ns)));
    EXPECT_TRUE(reader.groundTruthAt(c->stamp_ns));
    if (n == kScans / 2) {
      std::ifstream bin(drive.scan_files[n], std::ios::binary | std::ios::ate);
      EXPECT_EQ(size_t(bin.tellg()), c->cloud->size() * 16);
      // The GNSS position at the cloud's stamp is that scan's OXTS record (stamps a few ms
      // apart: 2e-6 deg is 0.2 m).
      OxtsRecord oxts;
      ASSERT_TRUE(readOxtsFile(drive.oxts_files[n], oxts, &error)) << error;
      const auto at = inputs.fixAt(seconds(c->stamp_ns));
      ASSERT_TRUE(at);
      EXPECT_NEAR(at->lat, oxts.lat, 2e-6);
      EXPECT_NEAR(at->lon, oxts.lon, 2e-6);
    }
    ++n;
  }
  EXPECT_EQ(n, size_t(kScans));
  // Look-ups further away than max_dt find nothing.
  EXPECT_FALSE(reader.groundTruthAt(drive.scan_stamps.back() + 1000000000LL));
  EXPECT_FALSE(inputs.attitudeAt(seconds(drive.scan_stamps.front() - 1000000000LL)));
  EXPECT_FALSE(inputs.fixAt(seconds(drive.scan_stamps.back() + 1000000000LL)));
}

TEST_F(OfflineSlamBag, BagAndKittiRawGiveTheSameTrajectory) {
  std::string log;
  const fs::path kitti_out = D->dir / "out_kitti", bag_out = D->dir / "out_bag";
  ASSERT_EQ(run(offlineSlam("--kitti-raw '" + D->drive_dir.string() + "'", kitti_out), &log), 0)
      << log;
  ASSERT_EQ(run(offlineSlam("--bag '" + D->bag.string() + "'", bag_out), &log), 0) << log;
  std::cout << log;

  for (const char* f :
       {"map.pcd", "buildings_corrected.geojson", "buildings_corrected.osm",
        "buildings_prior.geojson", "trajectory_kitti.txt", "trajectory_tum.txt", "graph.g2o",
        "odometry_tum.txt", "ground_truth_tum.txt", "timing.txt", "timing.json"})
    EXPECT_TRUE(fs::exists(bag_out / f)) << f;

  for (const char* f : {"trajectory_tum.txt", "odometry_tum.txt", "ground_truth_tum.txt"}) {
    const TrajectoryReadResult a = readTrajectory((kitti_out / f).string());
    const TrajectoryReadResult b = readTrajectory((bag_out / f).string());
    ASSERT_TRUE(a.ok && b.ok) << a.error << b.error;
    ASSERT_EQ(a.trajectory.size(), b.trajectory.size()) << f;
    EXPECT_GE(a.trajectory.size(), 10u) << f;
    double max_dp = 0.0, max_dr = 0.0;
    for (size_t i = 0; i < a.trajectory.size(); ++i) {
      EXPECT_NEAR(a.trajectory[i].stamp, b.trajectory[i].stamp, 1e-6) << f;
      const Eigen::Isometry3d d = a.trajectory[i].pose.inverse() * b.trajectory[i].pose;
      max_dp = std::max(max_dp, d.translation().norm());
      max_dr = std::max(max_dr, Eigen::AngleAxisd(d.linear()).angle());
    }
    std::cout << "[offline_slam_bag] " << f << ": " << a.trajectory.size()
              << " poses, max difference " << max_dp * 1000 << " mm, " << max_dr * 180 / M_PI
              << " deg\n";
    // Same clouds bit for bit, attitude and heading equal to 1e-15 (quaternion round trip): the
    // runs are deterministic, so only round-off may differ (measured: 1e-14 m).
    EXPECT_LT(max_dp, 1e-6) << f;
    EXPECT_LT(max_dr, 1e-8) << f;
  }
  const BuildingFileResult a =
      readBuildingsGeoJson((kitti_out / "buildings_corrected.geojson").string());
  const BuildingFileResult b =
      readBuildingsGeoJson((bag_out / "buildings_corrected.geojson").string());
  ASSERT_TRUE(a.ok && b.ok) << a.error << b.error;
  EXPECT_EQ(a.buildings.size(), b.buildings.size());
  EXPECT_GE(a.buildings.size(), 3u) << "no building reached the back-end";
  // The prior the back-end used, in the same format, next to the corrected outlines (what
  // scripts/plot_map_overlay.py draws): the same buildings by id, with their outlines in lat/lon.
  const BuildingFileResult prior =
      readBuildingsGeoJson((kitti_out / "buildings_prior.geojson").string());
  ASSERT_TRUE(prior.ok) << prior.error;
  ASSERT_EQ(prior.buildings.size(), a.buildings.size());
  std::set<int64_t> prior_ids, corrected_ids;
  for (const Building& p : prior.buildings) {
    prior_ids.insert(p.id);
    EXPECT_GE(p.outline_geo.size(), 3u) << p.id;
  }
  for (const Building& c : a.buildings) corrected_ids.insert(c.id);
  EXPECT_EQ(prior_ids, corrected_ids);
}

TEST_F(OfflineSlamBag, TopicNamesAreOptionsAndBadInputIsReported) {
  // A bag with other topic names, read with the matching options.
  KittiRawBagOptions bag;
  bag.drive_dir = D->drive_dir.string();
  bag.bag_path = (D->dir / "renamed.bag").string();
  bag.cloud_topic = "points_raw";
  bag.gps_topic = "fix";
  bag.imu_topic = "imu";
  bag.ground_truth_topic = "truth";
  ASSERT_TRUE(convertKittiRawToBag(bag).ok);
  std::string log;
  const std::string renamed = "--bag '" + bag.bag_path + "' --max-scans 15 ";
  EXPECT_EQ(run(offlineSlam(renamed, D->dir / "out_renamed"), &log), 1);
  EXPECT_NE(log.find("no message on topic 'velodyne_points'"), std::string::npos) << log;
  EXPECT_EQ(run(offlineSlam(renamed + "--cloud-topic points_raw --gps-topic fix --imu-topic imu "
                                      "--ground-truth-topic truth",
                            D->dir / "out_renamed"),
                &log),
            0)
      << log;
  const TrajectoryReadResult truth =
      readTrajectory((D->dir / "out_renamed" / "ground_truth_tum.txt").string());
  ASSERT_TRUE(truth.ok) << truth.error;
  EXPECT_GE(truth.trajectory.size(), 3u);
  // Without the IMU topic there is no initial heading: a clear error, unless global matching.
  EXPECT_EQ(run(offlineSlam(renamed + "--cloud-topic points_raw --gps-topic fix",
                            D->dir / "out_renamed2"),
                &log),
            1);
  EXPECT_NE(log.find("no IMU orientation"), std::string::npos) << log;

  // A missing bag, a file that is not a bag, both inputs at once.
  EXPECT_EQ(
      run(offlineSlam("--bag '" + (D->dir / "missing.bag").string() + "'", D->dir / "x"), &log), 1);
  EXPECT_NE(log.find("cannot read bag"), std::string::npos) << log;
  std::ofstream(D->dir / "not_a.bag") << "hello";
  EXPECT_EQ(run(offlineSlam("--bag '" + (D->dir / "not_a.bag").string() + "'", D->dir / "x"), &log),
            1);
  EXPECT_NE(log.find("cannot read bag"), std::string::npos) << log;
  EXPECT_EQ(run(offlineSlam("--bag a.bag --kitti-raw b", D->dir / "x"), &log), 2);
  EXPECT_FALSE(fs::exists(D->dir / "x"));
}

}  // namespace
}  // namespace osm_graph_slam
