// Rostest node for osm_localization.test (issue 21 item 4): launch/osm_localization.launch
// localises a replayed bag from OSM alone (no saved map): prefiltering, scan_matching, osm_buffer
// reading the drive's perturbed OSM prior from a file, and the osm_localization nodelet.
//
// Fixture, generated at test time into the build tree (a lock-protected cache keyed by the
// command and the tools' stamps; nothing committed): simulate_urban drives through the Karlsruhe
// extract (seed 2, HDL-64E, the simulator's consumer GNSS: white noise plus a slowly varying
// bias) and kitti2bag turns the drive into a bag; the prior (prior.osm: every building moved on
// its own) is kept beside it. The launch file's osm_buffer is swapped by this node for one
// reading that prior. Asserted: the share of scans localised, the mean error against the bag's
// ground truth (an absolute bound, and below the raw fixes'), buildings received and wall
// matches accepted.
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/NavSatFix.h>

#include <mutex>

#include "osm_graph_slam/OsmLocalizationReport.h"
#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "osm_graph_slam/ros/conversions.h"
#include "slam_regression_common.h"

namespace osm_graph_slam {
namespace {

using namespace regression;

struct Sample {
  double stamp;
  std::string status;
  Eigen::Isometry3d pose;
};

struct Fixture {
  fs::path dir;
  std::string bag, prior;
  std::unique_ptr<BagDriveReader> truth;
  std::mutex mutex;
  std::vector<Sample> samples;
  uint32_t osm_accepted = 0, buildings = 0;
  std::string error;
};
Fixture* R = nullptr;

std::string prepareFixture(Fixture& r) {
  ros::NodeHandle pnh("~");
  r.dir = cacheDir(pnh, "osm_localization_test_data");
  std::error_code ec;
  FileLock lock(r.dir / "lock");
  if (!lock.ok()) return "cannot lock " + (r.dir / "lock").string();
  const std::string osm = test::sharedDataPath("osm/2011_09_26_drive_0005_sync.osm");
  const std::string world = fs::exists(osm) ? " --osm '" + osm + "'" : std::string();
  const std::string sim = "'" + toolPath("simulate_urban") + "' --out '" +
                          (r.dir / "sim").string() + "' --scans " +
                          std::to_string(pnh.param("scans", 300)) +
                          " --seed 2 --length 400 --motion-distortion" + world;
  const std::string key = sim + "\n" + fileStamp(toolPath("simulate_urban")) +
                          fileStamp(toolPath("kitti2bag")) + (world.empty() ? "" : fileStamp(osm));
  r.bag = (r.dir / "drive.bag").string();
  r.prior = (r.dir / "prior.osm").string();
  if (readText(r.dir / "key.txt") == key && fs::exists(r.bag) && fs::exists(r.prior)) {
    std::cout << "[osm_localization_test] fixture from the cache " << r.dir << std::endl;
    return "";
  }
  fs::remove(r.dir / "key.txt", ec);
  fs::remove_all(r.dir / "sim", ec);
  const fs::path log = r.dir / "generation.log";
  fs::remove(log, ec);
  if (runLogged(sim, log) != 0) return "simulate_urban failed:\n" + readText(log);
  const nlohmann::json info =
      nlohmann::json::parse(readText(r.dir / "sim" / "sim_info.json"), nullptr, false);
  if (info.is_discarded() || !info.contains("drive_dir")) return "no usable sim_info.json";
  const std::string drive = (r.dir / "sim" / info["drive_dir"].get<std::string>()).string();
  if (runLogged("'" + toolPath("kitti2bag") + "' '" + drive + "' '" + r.bag + "'", log) != 0)
    return "kitti2bag failed:\n" + readText(log);
  fs::copy_file(r.dir / "sim" / "prior.osm", r.prior, fs::copy_options::overwrite_existing, ec);
  if (ec) return "no prior.osm from simulate_urban: " + ec.message();
  fs::remove_all(r.dir / "sim", ec);
  std::ofstream(r.dir / "key.txt.tmp") << key;
  fs::rename(r.dir / "key.txt.tmp", r.dir / "key.txt", ec);
  return "";
}

void onStatus(const OsmLocalizationReport::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(R->mutex);
  R->samples.push_back({msg->header.stamp.toSec(), msg->status, fromPoseMsg(msg->pose.pose)});
  R->osm_accepted = msg->osm_accepted;
  R->buildings = msg->buildings;
}

class OsmLocalizationRostest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    R = new Fixture;
    R->error = setUp();
  }
  static std::string setUp() {
    std::string error = prepareFixture(*R);
    if (!error.empty()) return error;
    R->truth = std::make_unique<BagDriveReader>();
    if (!R->truth->open(R->bag, {}, &error)) return error;
    std::string manager = "/osm_localization_manager";
    ros::NodeHandle("~").param("manager", manager, manager);
    // osm_buffer reads the drive's prior (the launch file's had no file to read) and queries
    // around the localised pose, as the launch file remaps it.
    error = swapNodelet(manager, "/osm_buffer", "osm_graph_slam/OsmBufferNodelet", "osm_file",
                        R->prior, {{"/slam/pose", "/osm_localization/pose"}});
    if (!error.empty()) return error;
    ros::NodeHandle nh;
    ros::Subscriber status_sub = nh.subscribe("osm_localization/status", 1000, onStatus);
    error = playBag(
        R->bag, param("play_rate", 1.0), (R->dir / "rosbag_play.log").string(), [] {},
        param("replay_timeout", 150.0));
    if (!error.empty()) return error;
    ros::WallDuration(1.0).sleep();  // the last scans through the nodelets
    return "";
  }
  void SetUp() override { ASSERT_TRUE(R->error.empty()) << R->error; }
};

TEST_F(OsmLocalizationRostest, LocalisesTheBagFromOsmAloneBetterThanItsFixes) {
  std::lock_guard<std::mutex> lock(R->mutex);
  ASSERT_GT(R->samples.size(), 100u);
  // The truth and the localiser share the frame: ENU at the first fix (kitti2bag's ground truth,
  // osm_buffer's origin).
  size_t localized = 0, with_truth = 0;
  double sum = 0.0, max_e = 0.0;
  for (const Sample& s : R->samples) {
    if (s.status == "uninitialized") continue;
    ++localized;
    const auto truth = R->truth->groundTruthAt(std::llround(s.stamp * 1e9), 0.02);
    if (!truth) continue;
    ++with_truth;
    const double e = (s.pose.translation() - truth->translation()).head<2>().norm();
    sum += e;
    max_e = std::max(max_e, e);
  }
  // The raw fixes against the same truth.
  double fix_sum = 0.0;
  size_t fixes = 0;
  const auto origin = R->truth->firstFix();
  ASSERT_TRUE(origin.has_value());
  const EnuConverter enu(origin->lat, origin->lon, origin->alt);
  for (const BagFix& f : R->truth->fixes()) {
    const auto truth = R->truth->groundTruthAt(f.stamp_ns, 0.02);
    if (!truth) continue;
    fix_sum += (enu.toEnu(f.lat, f.lon, f.alt).head<2>() - truth->translation().head<2>()).norm();
    ++fixes;
  }
  const double mean = with_truth ? sum / with_truth : 1e9;
  const double fix_mean = fixes ? fix_sum / fixes : 0.0;
  std::printf(
      "[osm_localization_test] %zu status messages, %zu localised (%zu with truth): error mean "
      "%.3f m (max %.3f); raw fixes %.3f m (%zu); %u wall matches accepted, %u buildings held\n",
      R->samples.size(), localized, with_truth, mean, max_e, fix_mean, fixes, R->osm_accepted,
      R->buildings);
  std::fflush(stdout);
  EXPECT_GE(double(localized), param("min_localized_share", 0.9) * double(R->samples.size()));
  EXPECT_GT(with_truth, 100u);
  EXPECT_LT(mean, param("max_mean_error_m", 1.5));
  EXPECT_LT(mean, fix_mean) << "no better than the GNSS fixes alone";
  EXPECT_GT(R->buildings, 10u) << "osm_buffer's buildings never reached the localiser";
  EXPECT_GT(R->osm_accepted, param("min_wall_matches", 10.0)) << "the walls were not used";
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  return osm_graph_slam::regression::rostestMain(argc, argv, "osm_localization_test");
}
