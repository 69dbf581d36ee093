// kitti2bag / mulran2bag conversions: fixtures written here in a temp dir, plus the real KITTI
// scans of ../shared/data (symlinked, never copied into the repository).
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "bag_test_utils.h"
#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace osm_graph_slam;

namespace {

using test::fileBytes;
using test::readTopic;
using test::writeFile;

fs::path freshDir(const std::string& name) {
  return test::freshFolder(fs::path(::testing::TempDir()) / ("ogs_dataset_bag_" + name));
}

void writeScan(const fs::path& path, const std::vector<float>& xyzi) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(xyzi.data()), xyzi.size() * sizeof(float));
}

/// A KITTI raw drive with n scans (given files or synthetic points) and n OXTS records moving
/// 1 m east per frame from (49.0, 8.4).
fs::path writeKittiRawFixture(const fs::path& root, const std::vector<std::string>& real_scans,
                              size_t n) {
  const fs::path date = root / "2011_09_26";
  const fs::path drive = date / "2011_09_26_drive_0001_sync";
  std::string stamps;
  for (size_t i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%010zu", i);
    const fs::path scan = drive / "velodyne_points" / "data" / (std::string(name) + ".bin");
    if (i < real_scans.size()) {
      fs::create_directories(scan.parent_path());
      fs::create_symlink(real_scans[i], scan);
    } else {
      std::vector<float> pts;
      for (int k = 0; k < 50; ++k) {
        pts.insert(pts.end(), {0.1f * k + float(i), -0.37f * k, 1e-7f * k, 0.01f * k});
      }
      writeScan(scan, pts);
    }
    char ts[64];
    std::snprintf(ts, sizeof(ts), "2011-09-26 13:02:%02zu.%09zu\n", 25 + i, 100000007 * (i + 1));
    stamps += ts;
    OxtsRecord r;
    r.lat = 49.0;
    r.lon = 8.4 + i * (1.0 / (111320.0 * std::cos(49.0 * M_PI / 180.0)));
    r.alt = 112.0;
    r.yaw = 0.1 * i;
    r.vf = 10.0;
    r.af = 0.5;
    r.au = 9.81;
    r.wu = 0.2;
    r.pos_accuracy = 0.05;
    fs::create_directories(drive / "oxts" / "data");
    EXPECT_TRUE(
        writeOxtsFile((drive / "oxts" / "data" / (std::string(name) + ".txt")).string(), r));
  }
  writeFile(drive / "velodyne_points" / "timestamps.txt", stamps);
  writeFile(drive / "oxts" / "timestamps.txt", stamps);
  writeFile(date / "calib_imu_to_velo.txt",
            "calib_time: 25-May-2012 16:47:16\nR: 1 0 0 0 1 0 0 0 1\nT: -0.81 0.32 -0.8\n");
  writeFile(date / "calib_velo_to_cam.txt",
            "calib_time: 15-Mar-2012 11:37:16\nR: 0 -1 0 0 0 -1 1 0 0\nT: 0 -0.08 -0.27\n"
            "delta_f: 0 0\ndelta_c: 0 0\n");
  return drive;
}

void expectBitExact(const sensor_msgs::PointCloud2& msg, const std::string& file) {
  const std::string bytes = fileBytes(file);
  ASSERT_EQ(msg.data.size(), bytes.size()) << file;
  EXPECT_EQ(std::memcmp(msg.data.data(), bytes.data(), bytes.size()), 0) << file;
  ASSERT_EQ(msg.fields.size(), 4u);
  EXPECT_EQ(msg.fields[3].name, "intensity");
  EXPECT_EQ(msg.point_step, 16u);
  EXPECT_EQ(msg.width * msg.height, bytes.size() / 16);
}

}  // namespace

TEST(Kitti2Bag, RawFixtureStampsFramesAndValues) {
  const fs::path root = freshDir("raw");
  const fs::path drive = writeKittiRawFixture(root, {}, 3);
  KittiRawBagOptions o;
  o.drive_dir = drive.string();
  o.bag_path = (root / "out.bag").string();
  size_t last_done = 0;
  const auto r = convertKittiRawToBag(o, [&](size_t done, size_t) { last_done = done; });
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(last_done, 6u);
  EXPECT_EQ(r.clouds, 3u);
  EXPECT_EQ(r.gps, 3u);

  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "velodyne_points");
  ASSERT_EQ(clouds.size(), 3u);
  StampNs s0;
  ASSERT_TRUE(parseKittiTimestamp("2011-09-26 13:02:25.100000007", s0));
  for (size_t i = 0; i < 3; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%010zu.bin", i);
    expectBitExact(clouds[i].second, (drive / "velodyne_points" / "data" / name).string());
    EXPECT_EQ(clouds[i].second.header.frame_id, "velo_link");
    const uint64_t expected = uint64_t(s0) + i * 1000000000ULL + i * 100000007ULL;
    EXPECT_EQ(clouds[i].second.header.stamp.toNSec(), expected);
    EXPECT_EQ(clouds[i].first.toNSec(), expected);
  }
  const auto fixes = readTopic<sensor_msgs::NavSatFix>(o.bag_path, "gps/fix");
  ASSERT_EQ(fixes.size(), 3u);
  EXPECT_DOUBLE_EQ(fixes[0].second.latitude, 49.0);
  EXPECT_NEAR(fixes[0].second.position_covariance[0], 0.0025, 1e-12);
  const auto imu = readTopic<sensor_msgs::Imu>(o.bag_path, "imu/data");
  ASSERT_EQ(imu.size(), 3u);
  EXPECT_DOUBLE_EQ(imu[1].second.linear_acceleration.z, 9.81);
  EXPECT_DOUBLE_EQ(imu[1].second.angular_velocity.z, 0.2);
  EXPECT_NEAR(2 * std::atan2(imu[2].second.orientation.z, imu[2].second.orientation.w), 0.2, 1e-9);
  EXPECT_EQ(imu[0].second.header.frame_id, "imu_link");

  // Ground truth: ENU anchored at the first fix, 1 m east per frame.
  const auto gt = readTopic<nav_msgs::Odometry>(o.bag_path, "ground_truth");
  ASSERT_EQ(gt.size(), 3u);
  EXPECT_EQ(gt[0].second.header.frame_id, "enu");
  EXPECT_EQ(gt[0].second.child_frame_id, "base_link");
  EXPECT_NEAR(gt[0].second.pose.pose.position.x, 0.0, 1e-9);
  EXPECT_NEAR(gt[2].second.pose.pose.position.x, 2.0, 0.01);
  EXPECT_NEAR(gt[2].second.pose.pose.position.y, 0.0, 0.01);
  EXPECT_DOUBLE_EQ(gt[2].second.twist.twist.linear.x, 10.0);

  const auto tf = readTopic<tf2_msgs::TFMessage>(o.bag_path, "tf_static");
  ASSERT_EQ(tf.size(), 1u);
  std::map<std::string, geometry_msgs::TransformStamped> by_child;
  for (const auto& t : tf[0].second.transforms) by_child[t.child_frame_id] = t;
  ASSERT_TRUE(by_child.count("velo_link"));
  EXPECT_EQ(by_child["velo_link"].header.frame_id, "base_link");
  EXPECT_NEAR(by_child["velo_link"].transform.translation.x, 0.81, 1e-12);
  EXPECT_NEAR(by_child["velo_link"].transform.translation.z, 0.80, 1e-12);
  EXPECT_TRUE(by_child.count("imu_link"));
  EXPECT_FALSE(fs::exists(o.bag_path + ".tmp"));
}

TEST(Kitti2Bag, RawNamesFirstMissingOrMalformedFile) {
  const fs::path root = freshDir("raw_bad");
  const fs::path drive = writeKittiRawFixture(root, {}, 3);
  KittiRawBagOptions o;
  o.drive_dir = drive.string();
  o.bag_path = (root / "out.bag").string();
  writeFile(drive / "oxts" / "data" / "0000000001.txt", "49.0 8.4 nonsense\n");
  auto r = convertKittiRawToBag(o);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("0000000001.txt"), std::string::npos) << r.error;
  EXPECT_FALSE(fs::exists(o.bag_path));
  fs::remove(root / "2011_09_26" / "calib_imu_to_velo.txt");
  r = convertKittiRawToBag(o);
  EXPECT_NE(r.error.find("calib_imu_to_velo.txt"), std::string::npos) << r.error;
  writeFile(drive / "velodyne_points" / "timestamps.txt", "2011-09-26 xx\n");
  r = convertKittiRawToBag(o);
  EXPECT_NE(r.error.find("velodyne_points/timestamps.txt"), std::string::npos) << r.error;
  std::ofstream(drive / "velodyne_points" / "data" / "0000000002.bin") << "0123456789";
  fs::remove_all(drive / "oxts");
  r = convertKittiRawToBag(o);
  EXPECT_NE(r.error.find("oxts/data"), std::string::npos) << r.error;
}

TEST(Kitti2Bag, RealPatchworkScansInRawLayoutAreBitExact) {
  std::vector<std::string> scans;
  for (int i = 0; i < 6; ++i) {
    scans.push_back(test::sharedDataPath("patchwork/00000" + std::to_string(i) + ".bin"));
    OGS_REQUIRE_SHARED_FILE(scans.back());
  }
  const fs::path root = freshDir("patchwork");
  const fs::path drive = writeKittiRawFixture(root, scans, 6);
  KittiRawBagOptions o;
  o.drive_dir = drive.string();
  o.bag_path = (root / "out.bag").string();
  const auto r = convertKittiRawToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "velodyne_points");
  ASSERT_EQ(clouds.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    expectBitExact(clouds[i].second, scans[i]);
    EXPECT_GT(clouds[i].second.width, 100000u);  // real HDL-64E scans
  }
}

TEST(Kitti2Bag, RealKitti00OdometryLayoutWithGroundTruthInLidarFrame) {
  const std::string a = test::sharedDataPath("kitti00/000094.bin");
  const std::string b = test::sharedDataPath("kitti00/000095.bin");
  const std::string poses = test::sharedDataPath("kitti00/poses_00_with_time.txt");
  OGS_REQUIRE_SHARED_FILE(a);
  OGS_REQUIRE_SHARED_FILE(b);
  OGS_REQUIRE_SHARED_FILE(poses);
  const fs::path root = freshDir("odometry");
  const fs::path seq = root / "sequences" / "00";
  fs::create_directories(seq / "velodyne");
  fs::create_symlink(a, seq / "velodyne" / "000000.bin");
  fs::create_symlink(b, seq / "velodyne" / "000001.bin");
  // Times and camera poses of frames 94 and 95 from the shared "time + 3x4" file.
  std::ifstream in(poses);
  std::string line, times, pose_rows;
  for (int i = 0; std::getline(in, line); ++i) {
    if (i != 94 && i != 95) continue;
    std::istringstream row(line);
    double t;
    row >> t;
    times += std::to_string(t) + "\n";
    std::string rest;
    std::getline(row, rest);
    pose_rows += rest + "\n";
  }
  writeFile(seq / "times.txt", times);
  writeFile(root / "poses" / "00.txt", pose_rows);
  writeFile(seq / "calib.txt",
            "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n"
            "Tr: 4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 "
            "-7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 "
            "9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01\n");
  KittiOdometryBagOptions o;
  o.sequence_dir = seq.string();
  o.bag_path = (root / "out.bag").string();
  const auto r = convertKittiOdometryToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.ground_truth, 2u);
  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "velodyne_points");
  ASSERT_EQ(clouds.size(), 2u);
  expectBitExact(clouds[0].second, a);
  expectBitExact(clouds[1].second, b);
  EXPECT_NEAR(clouds[0].second.header.stamp.toSec(), 1.0 + 9.745342, 1e-6);
  EXPECT_NEAR(clouds[1].second.header.stamp.toSec(), 1.0 + 9.849229, 1e-6);
  const auto gt = readTopic<nav_msgs::Odometry>(o.bag_path, "ground_truth");
  ASSERT_EQ(gt.size(), 2u);
  auto toIso = [](const nav_msgs::Odometry& m) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const auto& p = m.pose.pose;
    T.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
    T.linear() =
        Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z)
            .toRotationMatrix();
    return T;
  };
  const Eigen::Isometry3d rel = toIso(gt[0].second).inverse() * toIso(gt[1].second);
  // ../shared/data/kitti00/gt_relative_lidar.txt: |t| = 0.4748 m, yaw = -1.2356 deg.
  EXPECT_NEAR(rel.translation().norm(), 0.4748, 5e-4);
  EXPECT_NEAR(std::atan2(rel.linear()(1, 0), rel.linear()(0, 0)) * 180 / M_PI, -1.2356, 2e-3);
  EXPECT_EQ(gt[0].second.child_frame_id, "velo_link");
}

TEST(Mulran2Bag, FixtureOfDocumentedFormats) {
  const fs::path root = freshDir("mulran");
  const fs::path data = root / "sensor_data";
  const int64_t t0 = 1561000444390857630LL;
  std::string stamps, gps, imu, poses;
  std::vector<std::vector<float>> scans;
  for (int i = 0; i < 3; ++i) {
    const int64_t ts = t0 + i * 100000000LL;
    std::vector<float> pts;
    for (int k = 0; k < 64; ++k)
      pts.insert(pts.end(), {float(k) * 0.5f, -float(i), 0.25f * k, 17.0f + k});
    scans.push_back(pts);
    writeScan(data / "Ouster" / (std::to_string(ts) + ".bin"), pts);
    stamps += std::to_string(ts) + ",ouster\n";
    stamps += std::to_string(ts + 1000) + ",imu\n";
    imu += std::to_string(ts + 1000) +
           ",0,0,0.0998334,0.9950042,0,0,0.2,0.01,0.02,0.03,0.1,0.2,9.8,0.3,0.2,0.1\n";
    gps += std::to_string(ts + 2000) + ",37.5" + std::to_string(i) +
           ",127.36,55.2,4,0,0,0,4,0,0,0,16\n";
    stamps += std::to_string(ts + 2000) + ",gps\n";
    poses += std::to_string(ts) + ",1,0,0," + std::to_string(355630.0 + i) +
             ",0,1,0,4026700.5,0,0,1,19.5\n";
  }
  const int64_t radar_ts = t0 + 50000000LL;
  cv::Mat polar(400, 120, CV_8UC1);
  for (int r = 0; r < polar.rows; ++r) {
    for (int c = 0; c < polar.cols; ++c) polar.at<uint8_t>(r, c) = uint8_t((r * 7 + c) % 256);
  }
  fs::create_directories(data / "radar" / "polar");
  ASSERT_TRUE(cv::imwrite((data / "radar" / "polar" / (std::to_string(radar_ts) + ".png")).string(),
                          polar));
  stamps += std::to_string(radar_ts) + ",radar\n";
  writeFile(data / "data_stamp.csv", stamps);
  writeFile(data / "gps.csv", gps);
  writeFile(data / "xsens_imu.csv", imu);
  writeFile(root / "global_pose.csv", poses);

  MulranBagOptions o;
  o.root = root.string();
  o.bag_path = (root / "out.bag").string();
  auto r = convertMulranToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.clouds, 3u);
  EXPECT_EQ(r.images, 1u);
  EXPECT_EQ(r.gps, 3u);
  EXPECT_EQ(r.imu, 3u);
  EXPECT_EQ(r.ground_truth, 3u);

  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "os1_points");
  ASSERT_EQ(clouds.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(clouds[i].second.header.stamp.toNSec(), uint64_t(t0 + i * 100000000LL));
    ASSERT_EQ(clouds[i].second.data.size(), scans[i].size() * 4);
    EXPECT_EQ(std::memcmp(clouds[i].second.data.data(), scans[i].data(), scans[i].size() * 4), 0);
    EXPECT_EQ(clouds[i].second.header.frame_id, "ouster");
  }
  const auto images = readTopic<sensor_msgs::Image>(o.bag_path, "radar/polar");
  ASSERT_EQ(images.size(), 1u);
  EXPECT_EQ(images[0].second.encoding, "mono8");
  EXPECT_EQ(images[0].second.height, 400u);
  EXPECT_EQ(images[0].second.width, 120u);
  EXPECT_EQ(images[0].second.data[5 * 120 + 7], uint8_t((5 * 7 + 7) % 256));
  EXPECT_EQ(images[0].second.header.stamp.toNSec(), uint64_t(radar_ts));
  const auto fixes = readTopic<sensor_msgs::NavSatFix>(o.bag_path, "gps/fix");
  ASSERT_EQ(fixes.size(), 3u);
  EXPECT_DOUBLE_EQ(fixes[2].second.latitude, 37.52);
  EXPECT_DOUBLE_EQ(fixes[0].second.position_covariance[8], 16.0);
  const auto imus = readTopic<sensor_msgs::Imu>(o.bag_path, "imu/data");
  ASSERT_EQ(imus.size(), 3u);
  EXPECT_NEAR(imus[0].second.orientation.z, 0.0998334, 1e-6);
  EXPECT_DOUBLE_EQ(imus[0].second.linear_acceleration.z, 9.8);
  const auto gt = readTopic<nav_msgs::Odometry>(o.bag_path, "ground_truth");
  ASSERT_EQ(gt.size(), 3u);
  EXPECT_NEAR(gt[0].second.pose.pose.position.x, 0.0, 1e-9);  // relative to the first pose
  EXPECT_NEAR(gt[2].second.pose.pose.position.x, 2.0, 1e-9);

  // A scan listed in data_stamp.csv but absent: named in the error (or skipped on request).
  fs::remove(data / "Ouster" / (std::to_string(t0 + 100000000LL) + ".bin"));
  r = convertMulranToBag(o);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find(std::to_string(t0 + 100000000LL) + ".bin"), std::string::npos) << r.error;
  o.skip_missing = true;
  r = convertMulranToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.clouds, 2u);
  writeFile(data / "gps.csv", "1561000444390857630,37.5,127.3\n");
  r = convertMulranToBag(o);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("gps.csv' line 1"), std::string::npos) << r.error;
}
