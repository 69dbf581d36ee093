// The simulator's error sources: GNSS/INS errors of the OXTS records (white noise, Gauss-Markov
// bias, outages, attitude and heading bias, IMU noise), the exact records in oxts_true/ and their
// readers (openKittiRawDrive, kitti2bag, offline_slam --kitti-raw), and the prior-map error
// models (independent, blocks, global, mixed).
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/NavSatFix.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/sim/nav_errors.h"
#include "osm_graph_slam/sim/sim_random.h"
#include "osm_graph_slam/sim/simulator.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

constexpr double kDeg = M_PI / 180.0;

/// A small procedural city, no clutter: build() takes a fraction of a second.
SimulationParams smallDrive(uint64_t seed, double length = 600.0) {
  SimulationParams p;
  p.seed = seed;
  p.city.blocks_x = 4;
  p.city.blocks_y = 3;
  p.route.length = length;
  p.clutter_enabled = false;
  return p;
}

std::string fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

fs::path tempDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / name;
  fs::remove_all(dir);
  return dir;
}

double rms(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / double(v.size()));
}

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / double(v.size());
}

double stddev(const std::vector<double>& v) {
  const double m = mean(v);
  double s = 0.0;
  for (double x : v) s += (x - m) * (x - m);
  return v.size() < 2 ? 0.0 : std::sqrt(s / double(v.size() - 1));
}

/// White-noise sigma of a series with a slowly varying part: std of successive differences /
/// sqrt 2.
double whiteSigma(const std::vector<double>& v) {
  std::vector<double> d;
  for (size_t i = 1; i < v.size(); ++i) d.push_back(v[i] - v[i - 1]);
  return rms(d) / std::sqrt(2.0);
}

double wrap(double a) {
  return std::atan2(std::sin(a), std::cos(a));
}

/// Errors of the records written to oxts/ against the truth, per scan.
struct RecordErrors {
  std::vector<double> e, n, u, roll, pitch, yaw, gyro, accel;
  size_t outage_records = 0;
};

RecordErrors recordErrors(const UrbanSimulator& sim) {
  RecordErrors out;
  for (size_t k = 0; k < sim.numScans(); ++k) {
    const OxtsRecord m = sim.measuredOxts(k), t = sim.oxtsAt(sim.scanTime(k));
    out.roll.push_back(m.roll - t.roll);
    out.pitch.push_back(m.pitch - t.pitch);
    out.yaw.push_back(wrap(m.yaw - t.yaw));
    out.gyro.push_back(m.wz - t.wz);
    out.accel.push_back(m.ax - t.ax);
    if (!m.hasGnssFix()) {
      ++out.outage_records;
      continue;
    }
    const Eigen::Vector3d d =
        sim.enu().toEnu(m.lat, m.lon, m.alt) - sim.basePose(sim.scanTime(k)).translation();
    out.e.push_back(d.x());
    out.n.push_back(d.y());
    out.u.push_back(d.z());
  }
  return out;
}

std::string toolPath(const std::string& name) {
  // Tools and test binaries share build_ws/devel/lib/osm_graph_slam.
  return (fs::read_symlink("/proc/self/exe").parent_path() / name).string();
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// GNSS / INS

TEST(NavErrors, SameSeedSameBytesForTheNoisyOxts) {
  const fs::path a = tempDir("ogs_nav_det_a"), b = tempDir("ogs_nav_det_b");
  std::string drive_a, drive_b;
  for (const auto& dir : {a, b}) {
    SimulationParams p = smallDrive(11, 300.0);
    p.max_scans = 3;
    UrbanSimulator sim;
    std::string error;
    ASSERT_TRUE(sim.build(p, &error)) << error;
    SimulationStats stats;
    ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
    (dir == a ? drive_a : drive_b) = stats.drive_dir;
  }
  size_t compared = 0;
  for (const char* sub : {"oxts", "oxts_true"}) {
    for (const auto& entry : fs::recursive_directory_iterator(fs::path(drive_a) / sub)) {
      if (!entry.is_regular_file()) continue;
      const fs::path rel = fs::relative(entry.path(), drive_a);
      EXPECT_EQ(fileBytes(entry.path()), fileBytes(fs::path(drive_b) / rel)) << rel;
      ++compared;
    }
  }
  EXPECT_EQ(compared, 8u);  // 3 records + timestamps, twice
  EXPECT_EQ(fileBytes(a / "sim_info.json"), fileBytes(b / "sim_info.json"));
  // The noisy record is not the true one; the true one is oxts_true.
  const std::string rec = "data/0000000001.txt";
  EXPECT_NE(fileBytes(fs::path(drive_a) / "oxts" / rec),
            fileBytes(fs::path(drive_a) / "oxts_true" / rec));
  // Another seed, other errors.
  SimulationParams p = smallDrive(11, 300.0);
  UrbanSimulator s1, s2;
  ASSERT_TRUE(s1.build(p));
  p.seed = 12;
  ASSERT_TRUE(s2.build(p));
  EXPECT_NE(s1.navErrors().epochs[5].gnss, s2.navErrors().epochs[5].gnss);
}

TEST(NavErrors, ErrorProcessHasTheConfiguredStatistics) {
  // 20 drives of an hour each at 10 Hz, without outages: per-axis white and bias sigmas, the
  // bias' correlation time, and the stationarity of the bias from the first epoch on.
  NavErrorParams p;
  p.gnss_outages_per_km = 0.0;
  const double dt = 0.1;
  const std::vector<double> path(36000, 0.0);
  std::vector<double> white_e, white_u, bias_e, bias_u, first_bias, lag_products, lag_squares;
  const size_t lag = size_t(std::lround(p.gnss_bias_tau_s / dt));
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const NavErrorSequence s = simulateNavErrors(p, seed, dt, path);
    ASSERT_EQ(s.epochs.size(), path.size());
    first_bias.push_back(s.epochs[0].gnss_bias.x());
    for (size_t k = 0; k < s.epochs.size(); ++k) {
      const NavEpochError& e = s.epochs[k];
      EXPECT_FALSE(e.outage);
      white_e.push_back(e.gnss.x() - e.gnss_bias.x());
      white_u.push_back(e.gnss.z() - e.gnss_bias.z());
      bias_e.push_back(e.gnss_bias.x());
      bias_u.push_back(e.gnss_bias.z());
      if (k + lag < s.epochs.size()) {
        lag_products.push_back(e.gnss_bias.y() * s.epochs[k + lag].gnss_bias.y());
        lag_squares.push_back(e.gnss_bias.y() * e.gnss_bias.y());
      }
    }
  }
  EXPECT_NEAR(stddev(white_e), p.gnss_sigma, 0.02 * p.gnss_sigma);
  EXPECT_NEAR(stddev(white_u), p.gnss_sigma_vertical, 0.02 * p.gnss_sigma_vertical);
  // 20 h / 90 s = 800 independent bias samples per axis: sigma within ~10 %.
  EXPECT_NEAR(rms(bias_e), p.gnss_bias_sigma, 0.15 * p.gnss_bias_sigma);
  EXPECT_NEAR(rms(bias_u), p.gnss_bias_sigma_vertical, 0.15 * p.gnss_bias_sigma_vertical);
  // Correlation exp(-1) after one tau (0.37; a bias without memory gives 0, a constant one 1).
  EXPECT_NEAR(mean(lag_products) / mean(lag_squares), std::exp(-1.0), 0.08);
  // Stationary from the start: the first epoch's bias has the full sigma too (not zero).
  EXPECT_GT(rms(first_bias), 0.4 * p.gnss_bias_sigma);
  EXPECT_NEAR(gnssReportedAccuracy(p), std::hypot(1.5, 1.0), 1e-12);
}

TEST(NavErrors, DriveRecordsCarryTheConfiguredErrors) {
  SimulationParams p = smallDrive(3, 900.0);
  p.nav.gnss_outages_per_km = 0.0;
  UrbanSimulator sim;
  std::string error;
  ASSERT_TRUE(sim.build(p, &error)) << error;
  ASSERT_GT(sim.numScans(), 800u);
  const RecordErrors r = recordErrors(sim);
  EXPECT_EQ(r.outage_records, 0u);
  const NavErrorParams& nav = p.nav;
  // White noise from successive differences (the bias hardly moves in 0.1 s): within 10 %.
  EXPECT_NEAR(whiteSigma(r.e), nav.gnss_sigma, 0.1 * nav.gnss_sigma);
  EXPECT_NEAR(whiteSigma(r.n), nav.gnss_sigma, 0.1 * nav.gnss_sigma);
  EXPECT_NEAR(whiteSigma(r.u), nav.gnss_sigma_vertical, 0.1 * nav.gnss_sigma_vertical);
  // Total horizontal error per axis (white + one drive's bias): between half and twice the
  // reported accuracy, which is what kitti2bag puts into the NavSatFix covariance.
  const double total = std::sqrt(0.5 * (rms(r.e) * rms(r.e) + rms(r.n) * rms(r.n)));
  EXPECT_GT(total, 0.5 * gnssReportedAccuracy(nav));
  EXPECT_LT(total, 2.0 * gnssReportedAccuracy(nav));
  const OxtsRecord m = sim.measuredOxts(10);
  EXPECT_NEAR(m.pos_accuracy, gnssReportedAccuracy(nav), 1e-12);
  EXPECT_TRUE(m.hasGnssFix());
  // The records' errors are the model's (lat/lon round trip: < 1 mm).
  const NavEpochError& e10 = sim.navErrors().epochs[10];
  const Eigen::Vector3d d = sim.enu().toEnu(m.lat, m.lon, m.alt) -
                            sim.basePose(sim.scanTime(10)).translation() - e10.gnss;
  EXPECT_LT(d.norm(), 1e-3);

  // Heading: a constant bias of the configured magnitude (sign from the seed) plus white noise.
  EXPECT_NEAR(std::abs(sim.navErrors().heading_bias), nav.imu_heading_bias_deg * kDeg, 1e-12);
  EXPECT_NEAR(mean(r.yaw), sim.navErrors().heading_bias, 0.02 * kDeg);
  EXPECT_NEAR(std::abs(mean(r.yaw)), 0.3 * kDeg, 0.02 * kDeg);
  EXPECT_NEAR(stddev(r.yaw), nav.imu_heading_sigma_deg * kDeg,
              0.15 * nav.imu_heading_sigma_deg * kDeg);
  EXPECT_NEAR(stddev(r.roll), nav.imu_attitude_sigma_deg * kDeg,
              0.15 * nav.imu_attitude_sigma_deg * kDeg);
  EXPECT_NEAR(stddev(r.pitch), nav.imu_attitude_sigma_deg * kDeg,
              0.15 * nav.imu_attitude_sigma_deg * kDeg);
  EXPECT_NEAR(std::abs(mean(r.roll)), 0.0, 0.01 * kDeg);
  EXPECT_NEAR(stddev(r.gyro), nav.gyro_sigma_deg_s * kDeg, 0.15 * nav.gyro_sigma_deg_s * kDeg);
  EXPECT_NEAR(stddev(r.accel), nav.accel_sigma, 0.15 * nav.accel_sigma);

  // Both signs occur over seeds.
  std::set<int> signs;
  for (uint64_t seed = 1; seed <= 16; ++seed) {
    const NavErrorSequence s = simulateNavErrors(p.nav, seed, 0.1, std::vector<double>(2, 0.0));
    signs.insert(s.heading_bias > 0 ? 1 : -1);
  }
  EXPECT_EQ(signs.size(), 2u);
}

TEST(NavErrors, RtkGivesTheExactRecords) {
  SimulationParams p = smallDrive(3, 300.0);
  p.nav.rtk = true;
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  for (size_t k = 0; k < sim.numScans(); k += 7) {
    EXPECT_EQ(sim.measuredOxts(k).toArray(), sim.oxtsAt(sim.scanTime(k)).toArray()) << k;
    EXPECT_EQ(sim.navErrors().epochs[k].gnss, Eigen::Vector3d::Zero());
  }
  EXPECT_TRUE(sim.measuredOxts(0).hasGnssFix());
  EXPECT_NEAR(sim.measuredOxts(0).pos_accuracy, 0.02, 1e-12);  // as before the error models
  // The default (one place: NavErrorParams) is consumer-grade.
  EXPECT_FALSE(SimulationParams().nav.rtk);
}

TEST(NavErrors, OutagesHoldTheLastFixAndAreMarkedAsNoFix) {
  SimulationParams p = smallDrive(5, 900.0);
  p.nav.gnss_outages_per_km = 4.0;
  p.nav.gnss_outage_duration_s = 5.0;
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  const auto& epochs = sim.navErrors().epochs;
  int outages = 0;
  size_t outage_records = 0;
  for (size_t k = 0; k < sim.numScans(); ++k) {
    const OxtsRecord m = sim.measuredOxts(k);
    EXPECT_EQ(m.hasGnssFix(), !epochs[k].outage) << k;
    if (!epochs[k].outage) continue;
    ++outage_records;
    if (k == 0 || !epochs[k - 1].outage) ++outages;
    EXPECT_GE(sim.scanTime(k), p.nav.gnss_outage_min_start_s - 1e-9);
    EXPECT_EQ(m.numsats, 0);
    EXPECT_GE(m.pos_accuracy, kOxtsNoFixAccuracy);
    // The position is the last fix, held.
    size_t j = k;
    while (epochs[j].outage) --j;
    const OxtsRecord last = sim.measuredOxts(j);
    EXPECT_EQ(m.lat, last.lat);
    EXPECT_EQ(m.lon, last.lon);
    // The INS part stays valid: heading error as outside an outage.
    EXPECT_LT(std::abs(wrap(m.yaw - sim.oxtsAt(sim.scanTime(k)).yaw)), 1.0 * kDeg);
  }
  EXPECT_EQ(outages, sim.navErrors().outages);
  // ~3 expected over 900 m at 4 per km (gaps counted from each outage's end).
  EXPECT_GE(outages, 1);
  EXPECT_LE(outages, 10);
  // Each outage lasts 5 s = 50 records (the last one may be cut by the end of the drive).
  EXPECT_GE(outage_records, 50u * size_t(outages - 1));
  EXPECT_LE(outage_records, 50u * size_t(outages));
}

TEST(NavErrors, Kitti2bagMarksOutagesAndTakesTheTruthFromOxtsTrue) {
  const fs::path dir = tempDir("ogs_nav_bag");
  SimulationParams p = smallDrive(5, 300.0);
  p.max_scans = 8;
  p.nav.gnss_outage_min_start_s = 0.25;
  p.nav.gnss_outages_per_km = 1e6;  // an outage as soon as allowed
  p.nav.gnss_outage_duration_s = 0.3;
  UrbanSimulator sim;
  std::string error;
  ASSERT_TRUE(sim.build(p, &error)) << error;
  SimulationStats stats;
  ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
  EXPECT_GE(stats.gnss_outages, 1);
  std::vector<bool> fix;
  for (size_t k = 0; k < 8; ++k) fix.push_back(sim.measuredOxts(k).hasGnssFix());
  // No outage before 0.25 s, then one at once.
  EXPECT_EQ(std::vector<bool>(fix.begin(), fix.begin() + 4),
            std::vector<bool>({true, true, true, false}));

  KittiRawBagOptions o;
  o.drive_dir = stats.drive_dir;
  o.bag_path = (dir / "drive.bag").string();
  const BagConversionResult r = convertKittiRawToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.gps, 8u);
  EXPECT_EQ(r.ground_truth, 8u);
  {
    rosbag::Bag bag(o.bag_path, rosbag::bagmode::Read);
    std::vector<bool> status;
    for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("gps/fix"))) {
      const auto f = m.instantiate<sensor_msgs::NavSatFix>();
      ASSERT_TRUE(f);
      status.push_back(f->status.status >= sensor_msgs::NavSatStatus::STATUS_FIX);
      if (f->status.status >= sensor_msgs::NavSatStatus::STATUS_FIX) {
        // Honest covariance: pos_accuracy^2 horizontally.
        EXPECT_NEAR(f->position_covariance[0], std::pow(gnssReportedAccuracy(p.nav), 2), 1e-9);
      }
    }
    EXPECT_EQ(status, fix);
  }
  // Ground truth: the exact pose in the ENU frame of the (noisy) first fix, so the first pose is
  // minus the first fix's error, with the true heading.
  BagDriveReader reader;
  ASSERT_TRUE(reader.open(o.bag_path, BagDriveTopics(), &error)) << error;
  const NavEpochError& e0 = sim.navErrors().epochs[0];
  ASSERT_GT(e0.gnss.head<2>().norm(), 0.05);
  const auto gt0 = reader.groundTruthAt(sim.params().start_time_ns);
  ASSERT_TRUE(gt0);
  EXPECT_LT((gt0->translation() + e0.gnss).norm(), 0.01);
  const Eigen::Matrix3d R = gt0->linear();
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)), sim.oxtsAt(0).yaw, 1e-9);
  // The bag's fixes: the first valid is the origin; none during the outage (nearest only).
  ASSERT_TRUE(reader.firstFix());
  EXPECT_DOUBLE_EQ(reader.firstFix()->lat, sim.measuredOxts(0).lat);
}

TEST(NavErrors, KittiRawReaderExposesTheExactRecords) {
  const fs::path dir = tempDir("ogs_nav_reader");
  SimulationParams p = smallDrive(2, 300.0);
  p.max_scans = 3;
  UrbanSimulator sim;
  std::string error;
  ASSERT_TRUE(sim.build(p, &error)) << error;
  SimulationStats stats;
  ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
  KittiRawDrive drive;
  ASSERT_TRUE(openKittiRawDrive(stats.drive_dir, "", drive, &error)) << error;
  ASSERT_EQ(drive.truth_oxts_files.size(), 3u);
  EXPECT_EQ(drive.truth_oxts_stamps, drive.oxts_stamps);
  for (size_t k = 0; k < 3; ++k) {
    OxtsRecord truth, measured;
    ASSERT_TRUE(readOxtsFile(drive.truth_oxts_files[k], truth, &error)) << error;
    ASSERT_TRUE(readOxtsFile(drive.oxts_files[k], measured, &error)) << error;
    EXPECT_EQ(truth.toArray(), sim.oxtsAt(sim.scanTime(k)).toArray());  // %.17g round trip
    EXPECT_EQ(measured.toArray(), sim.measuredOxts(k).toArray());
  }
  // Malformed: stamps missing -> named; folder absent -> no truth files (real KITTI).
  const fs::path truth_dir = fs::path(stats.drive_dir) / "oxts_true";
  fs::rename(truth_dir / "timestamps.txt", dir / "ts.txt");
  EXPECT_FALSE(openKittiRawDrive(stats.drive_dir, "", drive, &error));
  EXPECT_NE(error.find("oxts_true/timestamps.txt"), std::string::npos) << error;
  fs::remove_all(truth_dir);
  ASSERT_TRUE(openKittiRawDrive(stats.drive_dir, "", drive, &error)) << error;
  EXPECT_TRUE(drive.truth_oxts_files.empty());
}

TEST(NavErrors, OfflineSlamTakesTheTruthFromOxtsTrue) {
  const std::string tool = toolPath("offline_slam");
  if (!fs::exists(tool)) GTEST_SKIP() << tool << " is not built";
  const fs::path dir = tempDir("ogs_nav_offline");
  SimulationParams p = smallDrive(2, 300.0);
  p.max_scans = 3;
  p.lidar = LidarModel::os1_64();  // smaller scans: a faster run
  UrbanSimulator sim;
  std::string error;
  ASSERT_TRUE(sim.build(p, &error)) << error;
  SimulationStats stats;
  ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
  const std::string cmd = "'" + tool + "' --kitti-raw '" + stats.drive_dir +
                          "' --no-osm --output '" + (dir / "out").string() + "' --config '" +
                          test::sourceDir() + "/config/sim.yaml' > '" + (dir / "log.txt").string() +
                          "' 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << fileBytes(dir / "log.txt");
  const TrajectoryReadResult truth =
      readTrajectory((dir / "out" / "ground_truth_tum.txt").string());
  ASSERT_TRUE(truth.ok) << truth.error;
  ASSERT_GE(truth.trajectory.size(), 1u);
  // The first keyframe is scan 0: its truth is the exact pose in the frame of the noisy first fix
  // (minus the fix's error), with the exact heading (the INS' has a 0.3 deg bias).
  const NavEpochError& e0 = sim.navErrors().epochs[0];
  ASSERT_GT(e0.gnss.head<2>().norm(), 0.05);
  const Eigen::Isometry3d& T = truth.trajectory.front().pose;
  EXPECT_LT((T.translation() + e0.gnss).norm(), 0.01);
  EXPECT_NEAR(std::atan2(T.linear()(1, 0), T.linear()(0, 0)), sim.oxtsAt(0).yaw, 1e-6);
}

// ------------------------------------------------------------------------------------------------
// Prior-map error models

namespace {

Scene sceneOf(const std::vector<Polygon2>& outlines) {
  Scene s;
  for (size_t i = 0; i < outlines.size(); ++i) {
    SimBuilding b;
    b.osm_id = int64_t(100 + i);
    b.outline = outlines[i];
    s.world.buildings.push_back(b);
    s.building_tags.push_back({{"building", "yes"}});
  }
  return s;
}

Polygon2 rect(double x0, double y0, double x1, double y1) {
  return {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0), Eigen::Vector2d(x1, y1),
          Eigen::Vector2d(x0, y1)};
}

/// Pairs (building, vertex) of different buildings at bit-identical coordinates.
std::vector<std::pair<std::pair<size_t, size_t>, std::pair<size_t, size_t>>> sharedVertices(
    const Scene& scene) {
  std::map<std::pair<double, double>, std::pair<size_t, size_t>> first;
  std::vector<std::pair<std::pair<size_t, size_t>, std::pair<size_t, size_t>>> out;
  const auto& bs = scene.world.buildings;
  for (size_t i = 0; i < bs.size(); ++i) {
    for (size_t v = 0; v < bs[i].outline.size(); ++v) {
      const auto key = std::make_pair(bs[i].outline[v].x(), bs[i].outline[v].y());
      auto it = first.find(key);
      if (it == first.end())
        first[key] = {i, v};
      else if (it->second.first != i)
        out.push_back({it->second, {i, v}});
    }
  }
  return out;
}

/// Every published building equals its true outline moved by its recorded rigid transform
/// (the prior_offsets.csv contract).
void expectOffsetsDescribeThePrior(const Scene& scene, const std::vector<PriorBuilding>& prior) {
  for (size_t i = 0; i < scene.world.buildings.size(); ++i) {
    const PriorBuilding& b = prior[i];
    ASSERT_EQ(b.osm_id, scene.world.buildings[i].osm_id);
    if (b.status != PriorBuilding::Status::kPerturbed) continue;
    const Eigen::Matrix2d R = Pose2(0, 0, b.dtheta).rotation();
    const Polygon2& t = scene.world.buildings[i].outline;
    ASSERT_EQ(b.outline.size(), t.size());
    for (size_t v = 0; v < t.size(); ++v) {
      const Eigen::Vector2d expected =
          R * (t[v] - b.centroid) + b.centroid + Eigen::Vector2d(b.dx, b.dy);
      EXPECT_LT((b.outline[v] - expected).norm(), 1e-6) << b.osm_id;
    }
  }
}

/// The prior of the original (independent) model, as the simulator computed it before the other
/// models existed: the reference that the default must still reproduce bit for bit.
std::vector<PriorBuilding> originalIndependentPrior(const Scene& scene,
                                                    const PriorPerturbationParams& p) {
  const auto& buildings = scene.world.buildings;
  const size_t n = buildings.size();
  SimRng rng(hashCombine(p.seed, 0x7072696f72ULL));
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  for (size_t i = n; i > 1; --i) std::swap(order[i - 1], order[rng.next() % i]);
  const size_t removed = size_t(std::llround(p.removal_fraction * double(n)));
  std::vector<bool> is_removed(n, false);
  for (size_t i = 0; i < removed && i < n; ++i) is_removed[order[i]] = true;
  std::vector<PriorBuilding> prior;
  for (size_t i = 0; i < n; ++i) {
    PriorBuilding b;
    b.osm_id = buildings[i].osm_id;
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& v : buildings[i].outline) c += v;
    b.centroid = c / double(buildings[i].outline.size());
    b.dx = p.translation_sigma * rng.gaussian();
    b.dy = p.translation_sigma * rng.gaussian();
    b.dtheta = p.rotation_sigma_deg * M_PI / 180.0 * rng.gaussian();
    if (is_removed[i]) {
      b.status = PriorBuilding::Status::kRemoved;
    } else {
      const Eigen::Matrix2d R = Pose2(0, 0, b.dtheta).rotation();
      for (const auto& v : buildings[i].outline)
        b.outline.push_back(R * (v - b.centroid) + b.centroid + Eigen::Vector2d(b.dx, b.dy));
    }
    prior.push_back(b);
  }
  return prior;
}

/// Way id -> node refs of prior.osm.
std::map<int64_t, std::vector<int64_t>> wayRefs(const std::string& xml) {
  std::map<int64_t, std::vector<int64_t>> out;
  std::istringstream in(xml);
  std::string line;
  int64_t way = 0;
  while (std::getline(in, line)) {
    long long id;
    if (std::sscanf(line.c_str(), " <way id=\"%lld\"", &id) == 1) way = id;
    if (std::sscanf(line.c_str(), " <nd ref=\"%lld\"", &id) == 1) out[way].push_back(id);
  }
  return out;
}

}  // namespace

TEST(PriorModels, IndependentIsTheOriginalModelBitForBit) {
  SimulationParams sp = smallDrive(4);
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(sp));
  PriorPerturbationParams p;
  EXPECT_EQ(p.model, PriorModel::kIndependent);  // the default
  p.seed = 4;
  const auto now = perturbBuildings(sim.scene(), p);
  const auto before = originalIndependentPrior(sim.scene(), p);
  ASSERT_GE(now.size(), before.size());
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_EQ(now[i].status, before[i].status);
    EXPECT_EQ(now[i].dx, before[i].dx);
    EXPECT_EQ(now[i].dy, before[i].dy);
    EXPECT_EQ(now[i].dtheta, before[i].dtheta);
    EXPECT_EQ(now[i].outline, before[i].outline);
  }
  expectOffsetsDescribeThePrior(sim.scene(), now);
}

TEST(PriorModels, BlocksMoveTouchingBuildingsTogetherAndKeepSharedNodes) {
  // Two buildings sharing an edge (two nodes), a third touching the second's wall with one
  // corner (a T: 1 cm off), and a fourth 200 m away.
  const Scene scene = sceneOf(
      {rect(0, 0, 10, 8), rect(10, 0, 20, 8), rect(20.01, 2, 30, 12), rect(200, 200, 212, 209)});
  PriorPerturbationParams p;
  p.model = PriorModel::kBlocks;
  p.removal_fraction = p.phantom_fraction = 0.0;
  p.block_size = 0.0;  // the touching components alone
  const std::vector<int> groups = priorBlockGroups(scene, p);
  EXPECT_EQ(groups, std::vector<int>({0, 0, 0, 1}));
  p.block_size = 1000.0;  // one cell: all in one block
  EXPECT_EQ(priorBlockGroups(scene, p), std::vector<int>({0, 0, 0, 0}));
  p.block_size = 80.0;
  EXPECT_EQ(priorBlockGroups(scene, p), std::vector<int>({0, 0, 0, 1}));

  for (uint64_t seed = 1; seed <= 5; ++seed) {
    p.seed = seed;
    const auto prior = perturbBuildings(scene, p);
    expectOffsetsDescribeThePrior(scene, prior);
    // The shared corners are bit-identical in the prior, and one rigid map moved the block.
    EXPECT_EQ(prior[0].outline[1], prior[1].outline[0]);
    EXPECT_EQ(prior[0].outline[2], prior[1].outline[3]);
    EXPECT_NEAR(prior[0].dtheta, prior[2].dtheta, 1e-15);
    EXPECT_GT((prior[0].outline[0] - scene.world.buildings[0].outline[0]).norm(), 1e-3);
    // The far building has its own offset.
    EXPECT_NE(prior[3].dtheta, prior[0].dtheta);
  }
  // prior.osm: the two shared corners are the same nodes in both ways.
  const fs::path dir = tempDir("ogs_prior_blocks");
  fs::create_directories(dir);
  const EnuConverter enu(49.0, 8.4, 100.0);
  ASSERT_TRUE(writePriorOsm((dir / "prior.osm").string(), perturbBuildings(scene, p), scene, enu));
  const auto refs = wayRefs(fileBytes(dir / "prior.osm"));
  ASSERT_EQ(refs.size(), 4u);
  const auto& a = refs.at(100);
  const auto& b = refs.at(101);
  EXPECT_EQ(a[1], b[0]);
  EXPECT_EQ(a[2], b[3]);
  std::set<int64_t> all;
  for (const auto& [id, r] : refs) all.insert(r.begin(), r.end() - 1);
  EXPECT_EQ(all.size(), 4u * 4u - 2u);

  // A per-building residual breaks them (it is off by default).
  p.block_residual_sigma = 0.2;
  const auto loose = perturbBuildings(scene, p);
  EXPECT_NE(loose[0].outline[1], loose[1].outline[0]);
  expectOffsetsDescribeThePrior(scene, loose);
}

TEST(PriorModels, BlocksKeepTheSharedNodesOfARealExtract) {
  const std::string path = test::sharedDataPath("osm/2011_09_26_drive_0005_sync.osm");
  OGS_REQUIRE_SHARED_FILE(path);
  const OsmData osm = readOsmFile(path);
  ASSERT_TRUE(osm.ok) << osm.error;
  const EnuConverter enu(49.0110, 8.4240, 115.0);
  const Scene scene = sceneFromOsm(osm, enu, 1);
  const auto shared = sharedVertices(scene);
  ASSERT_GT(shared.size(), 50u) << "the extract's touching buildings share nodes";
  PriorPerturbationParams p;
  p.model = PriorModel::kBlocks;
  PriorMapInfo info;
  const auto prior = perturbBuildings(scene, p, &info);
  expectOffsetsDescribeThePrior(scene, prior);
  EXPECT_GT(info.groups, 5u);
  EXPECT_LT(info.groups, scene.world.buildings.size() / 2);
  size_t kept = 0;
  for (const auto& [a, b] : shared) {
    if (prior[a.first].status != PriorBuilding::Status::kPerturbed ||
        prior[b.first].status != PriorBuilding::Status::kPerturbed)
      continue;
    EXPECT_EQ(prior[a.first].outline[a.second], prior[b.first].outline[b.second])
        << prior[a.first].osm_id << " / " << prior[b.first].osm_id;
    ++kept;
  }
  EXPECT_GT(kept, 40u);
  // With the independent model they come apart.
  p.model = PriorModel::kIndependent;
  const auto independent = perturbBuildings(scene, p);
  const auto& [a, b] = shared.front();
  EXPECT_NE(independent[a.first].outline[a.second], independent[b.first].outline[b.second]);
}

TEST(PriorModels, GlobalMovesEveryVertexByTheSameVector) {
  SimulationParams sp = smallDrive(6);
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(sp));
  const Scene& scene = sim.scene();
  std::vector<double> magnitudes;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    PriorPerturbationParams p;
    p.seed = seed;
    p.model = PriorModel::kGlobal;
    PriorMapInfo info;
    const auto prior = perturbBuildings(scene, p, &info);
    expectOffsetsDescribeThePrior(scene, prior);
    const Eigen::Vector2d shift = info.global_offset;
    magnitudes.push_back(shift.norm());
    EXPECT_GE(shift.norm(), 1.0 - 1e-12);
    EXPECT_LE(shift.norm(), 3.0 + 1e-12);
    size_t perturbed = 0, removed = 0;
    for (size_t i = 0; i < scene.world.buildings.size(); ++i) {
      if (prior[i].status == PriorBuilding::Status::kRemoved) {
        ++removed;
        continue;
      }
      ++perturbed;
      EXPECT_NEAR(prior[i].dx, shift.x(), 1e-9);
      EXPECT_NEAR(prior[i].dy, shift.y(), 1e-9);
      EXPECT_EQ(prior[i].dtheta, 0.0);
      for (size_t v = 0; v < prior[i].outline.size(); ++v)
        EXPECT_LT((prior[i].outline[v] - scene.world.buildings[i].outline[v] - shift).norm(), 1e-9);
    }
    // Removals and phantoms as in the independent model.
    EXPECT_EQ(removed, size_t(std::llround(0.05 * double(scene.world.buildings.size()))));
    p.model = PriorModel::kIndependent;
    const auto independent = perturbBuildings(scene, p);
    ASSERT_EQ(independent.size(), prior.size());
    for (size_t i = 0; i < prior.size(); ++i) {
      EXPECT_EQ(independent[i].status, prior[i].status);
      if (prior[i].status == PriorBuilding::Status::kPhantom) {
        EXPECT_EQ(independent[i].outline, prior[i].outline);
      }
    }
  }
  EXPECT_GT(*std::max_element(magnitudes.begin(), magnitudes.end()) -
                *std::min_element(magnitudes.begin(), magnitudes.end()),
            0.3);  // uniform in [1, 3], not a constant
  // A fixed magnitude.
  PriorPerturbationParams p;
  p.model = PriorModel::kGlobal;
  p.global_offset_min = p.global_offset_max = 2.0;
  PriorMapInfo info;
  perturbBuildings(scene, p, &info);
  EXPECT_NEAR(info.global_offset.norm(), 2.0, 1e-12);
}

TEST(PriorModels, MixedCombinesAllAndNamesParse) {
  SimulationParams sp = smallDrive(6);
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(sp));
  PriorPerturbationParams p;
  p.model = PriorModel::kMixed;
  PriorMapInfo info;
  const auto prior = perturbBuildings(sim.scene(), p, &info);
  expectOffsetsDescribeThePrior(sim.scene(), prior);
  EXPECT_GE(info.global_offset.norm(), 1.0);
  EXPECT_GT(info.groups, 1u);
  // Every building moved by global + block + its own offset: distinct per building.
  std::set<double> dthetas;
  for (const auto& b : prior)
    if (b.status == PriorBuilding::Status::kPerturbed) dthetas.insert(b.dtheta);
  EXPECT_GT(dthetas.size(), sim.scene().world.buildings.size() / 2);
  for (const char* name : {"independent", "blocks", "global", "mixed"}) {
    PriorModel m;
    ASSERT_TRUE(parsePriorModel(name, m)) << name;
    EXPECT_STREQ(priorModelName(m), name);
  }
  PriorModel m;
  EXPECT_FALSE(parsePriorModel("none", m));
}
