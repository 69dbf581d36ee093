// kitti2bag --scans: a folder of KITTI .bin scans with one georeference (no per-scan OXTS) -> a
// bag the ROS pipeline takes as it is: velodyne_points at start + i/rate, tf_static from the
// calibration, ONE gps/fix and (with an attitude) ONE imu/data at the first stamp. The real scans
// of ../shared/data/kitti_raw_0005 (the first three, unpacked into a temporary folder, never into
// the repository) and fixtures written here; skipped with a message when the real data is absent.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/NavSatFix.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "bag_test_utils.h"
#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace osm_graph_slam;

namespace {

using test::fileBytes;
using test::readTopic;
using test::writeFile;

const fs::path kTmp =
    fs::temp_directory_path() / ("ogs_kitti2bag_scans_" + std::to_string(::getpid()));

fs::path freshDir(const std::string& name) {
  return test::freshFolder(kTmp / name);
}

/// A scan of n points (x = i, y = 2, z = -1, intensity 0.5).
std::string scanBytes(size_t n) {
  std::vector<float> v;
  for (size_t i = 0; i < n; ++i) v.insert(v.end(), {float(i), 2.0f, -1.0f, 0.5f});
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float));
}

std::set<std::string> topicsOf(const std::string& bag_path) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag);
  std::set<std::string> topics;
  for (const auto* c : view.getConnections()) topics.insert(c->topic);
  return topics;
}

/// Whether the bag stores topic on a latched connection (rosbag play then latches it).
bool latched(const std::string& bag_path, const std::string& topic) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  rosbag::View view(bag, rosbag::TopicQuery(topic));
  bool all = !view.getConnections().empty();
  for (const auto* c : view.getConnections()) {
    const auto it = c->header->find("latching");
    all = all && it != c->header->end() && it->second == "1";
  }
  return all;
}

double yawOf(const geometry_msgs::Quaternion& q) {
  return std::atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z));
}

int run(const std::string& command, std::string* output) {
  const std::string log = (kTmp / "command.log").string();
  const int status = std::system((command + " > '" + log + "' 2>&1").c_str());
  *output = fileBytes(log);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class Kitti2BagScans : public ::testing::Test {
 protected:
  static void TearDownTestSuite() { fs::remove_all(kTmp); }
};

}  // namespace

TEST_F(Kitti2BagScans, RealKitti0005ScansWithOxtsOriginAndCalib) {
  const std::string archive = test::sharedDataPath("kitti_raw_0005/velodyne.tar.xz");
  const std::string oxts = test::sharedDataPath("kitti_raw_0005/oxts_frame0.txt");
  const std::string calib = test::sharedDataPath("kitti_raw_0005/calib_2011_09_26.txt");
  OGS_REQUIRE_SHARED_FILE(archive);
  OGS_REQUIRE_SHARED_FILE(oxts);
  OGS_REQUIRE_SHARED_FILE(calib);
  // The first three scans only (--occurrence: tar stops once it has them).
  const fs::path dir = freshDir("real");
  std::string out;
  ASSERT_EQ(run("tar xJf '" + archive + "' -C '" + dir.string() +
                    "' --occurrence=1 velodyne/0000000000.bin velodyne/0000000001.bin "
                    "velodyne/0000000002.bin",
                &out),
            0)
      << out;
  const fs::path scans = dir / "velodyne";

  ScanFolderBagOptions o;
  o.scans_dir = scans.string();
  o.origin_oxts = oxts;
  o.calib_path = calib;
  o.bag_path = (dir / "real.bag").string();
  const BagConversionResult r = convertScanFolderToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.clouds, 3u);
  EXPECT_EQ(r.gps, 1u);
  EXPECT_EQ(r.imu, 1u);
  EXPECT_EQ(r.skipped, 0u);
  EXPECT_EQ(r.ground_truth, 0u);
  EXPECT_DOUBLE_EQ(r.first_stamp, kScanFolderDefaultStart);  // oxts_frame0.txt has no stamp
  EXPECT_FALSE(fs::exists(o.bag_path + ".tmp"));
  EXPECT_EQ(topicsOf(o.bag_path),
            (std::set<std::string>{"velodyne_points", "gps/fix", "imu/data", "tf_static"}));
  // The single messages are latched: a late subscriber (prefiltering's TF listener, osm_buffer)
  // still gets them from rosbag play; the clouds are not.
  EXPECT_TRUE(latched(o.bag_path, "tf_static"));
  EXPECT_TRUE(latched(o.bag_path, "gps/fix"));
  EXPECT_TRUE(latched(o.bag_path, "imu/data"));
  EXPECT_FALSE(latched(o.bag_path, "velodyne_points"));

  // Clouds: 10 Hz from the fixed epoch, frame velo_link, the .bin bytes bit-exactly.
  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "velodyne_points");
  ASSERT_EQ(clouds.size(), 3u);
  const int64_t start_ns = static_cast<int64_t>(kScanFolderDefaultStart) * 1000000000LL;
  for (size_t i = 0; i < clouds.size(); ++i) {
    const auto& [t, c] = clouds[i];
    EXPECT_EQ(t.toNSec(), static_cast<uint64_t>(start_ns + int64_t(i) * 100000000LL)) << i;
    EXPECT_EQ(c.header.stamp, t);
    EXPECT_EQ(c.header.frame_id, "velo_link");
    char name[32];
    std::snprintf(name, sizeof(name), "%010zu.bin", i);
    const std::string bytes = fileBytes(scans / name);
    EXPECT_EQ(c.width * c.height, bytes.size() / 16);
    EXPECT_EQ(c.point_step, 16u);
    ASSERT_EQ(c.data.size(), bytes.size());
    EXPECT_EQ(std::memcmp(c.data.data(), bytes.data(), bytes.size()), 0) << "scan " << i;
  }

  // One fix at the first stamp: frame 0's OXTS position, the map origin.
  const auto fixes = readTopic<sensor_msgs::NavSatFix>(o.bag_path, "gps/fix");
  ASSERT_EQ(fixes.size(), 1u);
  EXPECT_EQ(fixes[0].first, clouds[0].first);
  EXPECT_EQ(fixes[0].second.header.stamp, clouds[0].first);
  EXPECT_EQ(fixes[0].second.header.frame_id, "imu_link");
  EXPECT_EQ(fixes[0].second.status.status, sensor_msgs::NavSatStatus::STATUS_FIX);
  EXPECT_DOUBLE_EQ(fixes[0].second.latitude, 49.011212804408);
  EXPECT_DOUBLE_EQ(fixes[0].second.longitude, 8.4228850417969);
  EXPECT_NEAR(fixes[0].second.altitude, 112.83492279053, 1e-9);

  // One IMU sample at the first stamp: the OXTS attitude (initial heading, roll/pitch).
  const auto imu = readTopic<sensor_msgs::Imu>(o.bag_path, "imu/data");
  ASSERT_EQ(imu.size(), 1u);
  EXPECT_EQ(imu[0].first, clouds[0].first);
  EXPECT_EQ(imu[0].second.header.frame_id, "imu_link");
  EXPECT_GE(imu[0].second.orientation_covariance[0], 0.0);
  EXPECT_NEAR(yawOf(imu[0].second.orientation), -1.2219096732051, 1e-9);

  // tf_static at the first stamp: base_link -> velo_link = inv(Tr_imu_to_velo), -> imu_link = I.
  Eigen::Isometry3d T_velo_imu;
  ASSERT_TRUE(readImuToVeloCalib(calib, T_velo_imu));
  const auto tfs = readTopic<tf2_msgs::TFMessage>(o.bag_path, "tf_static");
  ASSERT_EQ(tfs.size(), 1u);
  EXPECT_EQ(tfs[0].first, clouds[0].first);
  ASSERT_EQ(tfs[0].second.transforms.size(), 2u);
  const auto& velo = tfs[0].second.transforms[0];
  EXPECT_EQ(velo.header.frame_id, "base_link");
  EXPECT_EQ(velo.child_frame_id, "velo_link");
  const Eigen::Vector3d expected = T_velo_imu.inverse().translation();
  EXPECT_NEAR(velo.transform.translation.x, expected.x(), 1e-9);
  EXPECT_NEAR(velo.transform.translation.y, expected.y(), 1e-9);
  EXPECT_NEAR(velo.transform.translation.z, expected.z(), 1e-9);
  EXPECT_NEAR(velo.transform.translation.z, 0.80, 0.01);  // KITTI: the Velodyne 0.8 m above
  EXPECT_EQ(tfs[0].second.transforms[1].child_frame_id, "imu_link");
}

TEST_F(Kitti2BagScans, OriginWithYawRateStartTimeAndSkippedScans) {
  const fs::path dir = freshDir("yaw");
  writeFile(dir / "scans" / "000.bin", scanBytes(50));
  writeFile(dir / "scans" / "001.bin", std::string(17, '\0'));  // not a multiple of 16 bytes
  writeFile(dir / "scans" / "002.bin", "");                     // no points
  writeFile(dir / "scans" / "003.bin", scanBytes(40));
  writeFile(dir / "scans" / "notes.txt", "not a scan");
  ScanFolderBagOptions o;
  o.scans_dir = (dir / "scans").string();
  o.origin = "49.0,8.4,110,90";
  o.rate = 5.0;
  o.start_time = 100.0;
  o.bag_path = (dir / "yaw.bag").string();
  const BagConversionResult r = convertScanFolderToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.clouds, 2u);
  EXPECT_EQ(r.skipped, 2u);
  std::string warnings;
  for (const auto& w : r.warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find("001.bin"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("002.bin' has no points"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("no calibration"), std::string::npos) << warnings;

  // A skipped scan keeps its slot in time: scans 0 and 3 at 100.0 and 100.6 s.
  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "velodyne_points");
  ASSERT_EQ(clouds.size(), 2u);
  EXPECT_EQ(clouds[0].first.toNSec(), 100000000000ULL);
  EXPECT_EQ(clouds[1].first.toNSec(), 100600000000ULL);
  EXPECT_EQ(clouds[1].second.width, 40u);
  const auto fixes = readTopic<sensor_msgs::NavSatFix>(o.bag_path, "gps/fix");
  ASSERT_EQ(fixes.size(), 1u);
  EXPECT_EQ(fixes[0].first.toNSec(), 100000000000ULL);
  EXPECT_DOUBLE_EQ(fixes[0].second.latitude, 49.0);
  EXPECT_DOUBLE_EQ(fixes[0].second.longitude, 8.4);
  EXPECT_EQ(fixes[0].second.position_covariance_type,
            sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN);
  // The yaw (ENU, 90 deg = north) with a level attitude; rates and accelerations unknown.
  const auto imu = readTopic<sensor_msgs::Imu>(o.bag_path, "imu/data");
  ASSERT_EQ(imu.size(), 1u);
  EXPECT_NEAR(yawOf(imu[0].second.orientation), M_PI / 2, 1e-12);
  EXPECT_NEAR(imu[0].second.orientation.x, 0.0, 1e-12);
  EXPECT_NEAR(imu[0].second.orientation.y, 0.0, 1e-12);
  EXPECT_GE(imu[0].second.orientation_covariance[0], 0.0);
  EXPECT_EQ(imu[0].second.angular_velocity_covariance[0], -1.0);
  EXPECT_EQ(imu[0].second.linear_acceleration_covariance[0], -1.0);
  // Without a calibration base_link is the LiDAR frame.
  const auto tfs = readTopic<tf2_msgs::TFMessage>(o.bag_path, "tf_static");
  ASSERT_EQ(tfs.size(), 1u);
  EXPECT_EQ(tfs[0].second.transforms[0].transform.translation.z, 0.0);
  EXPECT_EQ(tfs[0].second.transforms[0].transform.rotation.w, 1.0);
}

TEST_F(Kitti2BagScans, OriginWithoutYawWritesNoImu) {
  const fs::path dir = freshDir("noyaw");
  writeFile(dir / "scans" / "0.bin", scanBytes(10));
  ScanFolderBagOptions o;
  o.scans_dir = (dir / "scans").string();
  o.origin = "49.0,8.4,110";
  o.bag_path = (dir / "noyaw.bag").string();
  const BagConversionResult r = convertScanFolderToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.imu, 0u);
  EXPECT_EQ(r.gps, 1u);
  EXPECT_TRUE(readTopic<sensor_msgs::Imu>(o.bag_path, "imu/data").empty());
  std::string warnings;
  for (const auto& w : r.warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find("global matching"), std::string::npos) << warnings;
}

TEST_F(Kitti2BagScans, StartTimeFromTheOxtsRecordsTimestamps) {
  // An OXTS record inside a KITTI raw oxts/data/ folder: its line of oxts/timestamps.txt.
  const fs::path dir = freshDir("stamped");
  writeFile(dir / "scans" / "0.bin", scanBytes(10));
  writeFile(dir / "scans" / "1.bin", scanBytes(10));
  OxtsRecord rec;
  rec.lat = 49.0;
  rec.lon = 8.4;
  rec.alt = 110;
  rec.yaw = 0.3;
  rec.pos_accuracy = 0.02;
  fs::create_directories(dir / "oxts" / "data");
  ASSERT_TRUE(writeOxtsFile((dir / "oxts" / "data" / "0000000001.txt").string(), rec));
  writeFile(dir / "oxts" / "timestamps.txt",
            "2011-09-26 13:02:25.000000000\n2011-09-26 13:02:25.103542000\n");
  ScanFolderBagOptions o;
  o.scans_dir = (dir / "scans").string();
  o.origin_oxts = (dir / "oxts" / "data" / "0000000001.txt").string();
  o.bag_path = (dir / "stamped.bag").string();
  const BagConversionResult r = convertScanFolderToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  StampNs expected = 0;
  ASSERT_TRUE(parseKittiTimestamp("2011-09-26 13:02:25.103542000", expected));
  const auto clouds = readTopic<sensor_msgs::PointCloud2>(o.bag_path, "velodyne_points");
  ASSERT_EQ(clouds.size(), 2u);
  EXPECT_EQ(clouds[0].first.toNSec(), static_cast<uint64_t>(expected));
  EXPECT_EQ(clouds[1].first.toNSec(), static_cast<uint64_t>(expected + 100000000));
  const auto imu = readTopic<sensor_msgs::Imu>(o.bag_path, "imu/data");
  ASSERT_EQ(imu.size(), 1u);
  EXPECT_NEAR(yawOf(imu[0].second.orientation), 0.3, 1e-12);
}

TEST_F(Kitti2BagScans, InputErrorsAreClearAndLeaveNoBag) {
  const fs::path dir = freshDir("errors");
  writeFile(dir / "scans" / "0.bin", scanBytes(10));
  writeFile(dir / "bad_oxts.txt", "49.0 8.4\n");
  writeFile(dir / "bad_calib.txt", "R: 1 0 0\nfoo: bar\n");
  fs::create_directories(dir / "empty");
  writeFile(dir / "unreadable" / "0.bin", std::string(20, '\0'));
  writeFile(dir / "unreadable" / "1.bin", std::string(3, '\0'));
  auto convert = [&](ScanFolderBagOptions o) {
    o.bag_path = (dir / "out.bag").string();
    if (o.scans_dir.empty()) o.scans_dir = (dir / "scans").string();
    const BagConversionResult r = convertScanFolderToBag(o);
    EXPECT_FALSE(r.ok);
    EXPECT_FALSE(fs::exists(dir / "out.bag"));
    EXPECT_FALSE(fs::exists(dir / "out.bag.tmp"));
    return r.error;
  };
  ScanFolderBagOptions o;
  o.origin = "49,8,110";
  o.scans_dir = (dir / "missing").string();
  EXPECT_NE(convert(o).find("does not exist"), std::string::npos);
  o.scans_dir = (dir / "empty").string();
  EXPECT_NE(convert(o).find("no .bin scans in"), std::string::npos);
  o.scans_dir = (dir / "unreadable").string();
  const std::string none = convert(o);
  EXPECT_NE(none.find("none of the 2 .bin files"), std::string::npos) << none;

  o = ScanFolderBagOptions();
  EXPECT_NE(convert(o).find("exactly one of --origin-oxts"), std::string::npos);
  o.origin = "49,8,110";
  o.origin_oxts = (dir / "bad_oxts.txt").string();
  EXPECT_NE(convert(o).find("exactly one of --origin-oxts"), std::string::npos);
  o.origin.clear();
  const std::string malformed = convert(o);
  EXPECT_NE(malformed.find("malformed OXTS file"), std::string::npos) << malformed;
  EXPECT_NE(malformed.find("bad_oxts.txt"), std::string::npos) << malformed;
  o.origin_oxts = (dir / "absent_oxts.txt").string();
  EXPECT_NE(convert(o).find("cannot open OXTS file"), std::string::npos);
  o.origin_oxts.clear();
  for (const std::string bad :
       {"49,8", "49,8,110,0,1", "49;8;110", "49,8,1x0", "95,8,110", "49,8,110,"}) {
    o.origin = bad;
    const std::string e = convert(o);
    EXPECT_NE(e.find("LAT,LON,ALT[,YAW_DEG]"), std::string::npos) << bad << ": " << e;
  }
  o.origin = "49,8,110";
  o.calib_path = (dir / "bad_calib.txt").string();
  const std::string calib = convert(o);
  EXPECT_NE(calib.find("bad_calib.txt"), std::string::npos) << calib;
  EXPECT_NE(calib.find("Tr_imu_to_velo"), std::string::npos) << calib;
  o.calib_path.clear();
  o.rate = 0.0;
  EXPECT_NE(convert(o).find("--rate must be > 0"), std::string::npos);
}

TEST_F(Kitti2BagScans, CommandLine) {
  const fs::path tool = fs::read_symlink("/proc/self/exe").parent_path() / "kitti2bag";
  if (!fs::exists(tool)) GTEST_SKIP() << tool << " is not built";
  const fs::path dir = freshDir("cli");
  writeFile(dir / "scans" / "0.bin", scanBytes(10));
  writeFile(dir / "scans" / "1.bin", std::string(5, '\0'));
  std::string out;
  EXPECT_EQ(run("'" + tool.string() + "' --scans '" + (dir / "scans").string() +
                    "' --origin 49,8,110,45 --rate 20 '" + (dir / "cli.bag").string() + "'",
                &out),
            0)
      << out;
  EXPECT_NE(out.find("1 clouds, 1 gps, 1 imu"), std::string::npos) << out;
  EXPECT_NE(out.find("1 scans skipped"), std::string::npos) << out;
  EXPECT_NE(out.find("warning: scan '"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(dir / "cli.bag"));
  // Scan-folder options without --scans, and --scans without a bag, are usage errors.
  EXPECT_EQ(run("'" + tool.string() + "' '" + (dir / "scans").string() + "' '" +
                    (dir / "x.bag").string() + "' --origin 49,8,110",
                &out),
            2);
  EXPECT_NE(out.find("need --scans"), std::string::npos) << out;
  EXPECT_EQ(
      run("'" + tool.string() + "' --scans '" + (dir / "scans").string() + "' --origin 49,8,110",
          &out),
      2);
  EXPECT_EQ(run("'" + tool.string() + "' --scans '" + (dir / "none").string() +
                    "' --origin 49,8,110 '" + (dir / "y.bag").string() + "'",
                &out),
            1);
  EXPECT_NE(out.find("does not exist"), std::string::npos) << out;
}
