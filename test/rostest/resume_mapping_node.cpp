// Rostest node for resume_mapping.test (issue 58): a saved map of the shared simulated drive's
// first scans (offline_slam), graph_backend reloaded with ~resume_map on it, the drive replayed
// from start_s on through the nodelets without GNSS priors. The session must be placed by the
// global localiser near where the saved map has the same stamp (both runs see the same bag, so
// the saved trajectory at a stamp is where the new one belongs), joined by inter-session loops,
// and mapped on after the saved map ends; save_map writes both sessions. With ~handover
// (handover_mapping.test) the localization nodelet tracks on the saved map first and graph_backend
// maps only once it has left it: the localiser's poses, then the new session's keyframes, must
// cover the drive and agree with the saved run.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <ros/topic.h>
#include <std_msgs/Bool.h>
#include <std_msgs/String.h>

#include <mutex>

#include "osm_graph_slam/LocalizationReport.h"
#include "osm_graph_slam/SaveMap.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/ros/conversions.h"
#include "slam_regression_common.h"

namespace osm_graph_slam {
namespace {

using namespace regression;

struct ResumeRun {
  Drive drive;
  fs::path dir, saved, out;
  std::string error;  ///< set-up failure
  bool handover = false;
  std::mutex mutex;      ///< guards localized (the spinner's threads)
  Trajectory localized;  ///< the localiser's poses it reported localised (handover)
  ros::Subscriber localization_sub;
};
ResumeRun* R = nullptr;

std::string managerName() {
  std::string manager = "/osm_graph_slam_manager";
  ros::NodeHandle("~").param("manager", manager, manager);
  return manager;
}

/// The pose of a trajectory at `stamp`, strictly within its stamps (interpolatePose).
std::optional<Eigen::Isometry3d> poseAt(const Trajectory& t, double stamp) {
  Eigen::Isometry3d pose;
  if (t.empty() || stamp < t.front().stamp || stamp > t.back().stamp ||
      !interpolatePose(t, stamp, 1e9, pose))
    return std::nullopt;
  return pose;
}

/// A hand-over: the localization nodelet on the saved map (its other parameters from the .test),
/// and its poses recorded.
std::string startLocalizer() {
  ros::param::set("/graph_backend/handover", true);
  ros::param::set("/localization/map_dir", (R->saved / "map_package").string());
  ros::NodeHandle nh;
  R->localization_sub = nh.subscribe<LocalizationReport>(
      "localization/status", 1000,
      boost::function<void(const LocalizationReportConstPtr&)>(
          [](const LocalizationReportConstPtr& msg) {
            if (!msg->localized) return;
            std::lock_guard<std::mutex> guard(R->mutex);
            R->localized.push_back({msg->header.stamp.toSec(), fromPoseMsg(msg->pose.pose)});
          }));
  return loadNodelet(managerName(), "/localization", "osm_graph_slam/LocalizationNodelet",
                     {{"odom", "localization/odom"}});
}

std::string setUp() {
  const ros::NodeHandle pnh("~");
  const DriveOptions o = driveOptionsFromParams(pnh);
  R->drive = prepareDrive(o);
  if (!R->drive.error.empty()) return R->drive.error;
  R->dir = fs::temp_directory_path() / ("ogs_resume_" + std::to_string(::getpid()));
  R->saved = R->dir / "saved";
  R->out = R->dir / "resumed";
  const int saved_scans = pnh.param("saved_scans", 350);
  if (runOfflineSlam(R->drive, R->saved, "--no-osm --max-scans " + std::to_string(saved_scans)) !=
      0)
    return "offline_slam (the saved map) failed:\n" + readText(R->saved.string() + ".log");
  R->handover = pnh.param("handover", false);
  if (R->handover) {
    const std::string loaded = startLocalizer();
    if (!loaded.empty()) return loaded;
  }
  const std::string swap =
      swapNodelet(managerName(), "/graph_backend", "osm_graph_slam/GraphBackendNodelet",
                  "resume_map", R->saved.string());
  if (!swap.empty()) return swap;
  if (!waitFor([] { return ros::service::exists("/graph_backend_test/save_map", false); }, 120.0))
    return "graph_backend_test/save_map never came up (replaying the saved map?)";
  const double rate = pnh.param("play_rate", 0.5), start = pnh.param("start_s", 12.0);
  const double duration = o.scans * 0.1 - start;
  return playBag(
      R->drive.bag, rate, (R->dir / "rosbag.log").string(), [] {}, 60.0 + 3.0 * duration / rate,
      start);
}

TEST(ResumeMapping, TheNewSessionIsPlacedOnTheSavedMapAndJoinedByLoops) {
  if (R->handover) GTEST_SKIP() << "handover_mapping.test";
  ASSERT_TRUE(R->error.empty()) << R->error;
  SaveMap srv;
  srv.request.destination = R->out.string();
  srv.request.resolution = 0.2;
  ASSERT_TRUE(ros::service::call("/graph_backend_test/save_map", srv));
  ASSERT_TRUE(srv.response.success) << srv.response.message;
  // save_map's message ends with the session's state; slam/resume_status says the same.
  const std::string& message = srv.response.message;
  std::cout << "[resume_mapping] save_map: " << message << std::endl;
  ASSERT_NE(message.find("placed at keyframe"), std::string::npos) << message;
  const std_msgs::StringConstPtr latched =
      ros::topic::waitForMessage<std_msgs::String>("slam/resume_status", ros::Duration(10.0));
  ASSERT_TRUE(latched != nullptr) << "no slam/resume_status";
  EXPECT_NE(latched->data.find("placed at keyframe"), std::string::npos) << latched->data;

  const TrajectoryReadResult saved_read =
      readTumTrajectory((R->saved / "trajectory_tum.txt").string());
  const TrajectoryReadResult merged_read =
      readTumTrajectory((R->out / "trajectory_tum.txt").string());
  ASSERT_TRUE(saved_read.ok) << saved_read.error;
  ASSERT_TRUE(merged_read.ok) << merged_read.error;
  const Trajectory& saved = saved_read.trajectory;
  const Trajectory& merged = merged_read.trajectory;
  ASSERT_GT(merged.size(), saved.size() + 10);
  // Both sessions are in the map: the saved keyframes first (held where they were saved).
  const Trajectory live(merged.begin() + static_cast<std::ptrdiff_t>(saved.size()), merged.end());
  std::vector<double> errors, yaws;
  size_t beyond = 0;
  for (const auto& kf : live) {
    const auto at = poseAt(saved, kf.stamp);
    if (!at) {
      beyond += kf.stamp > saved.back().stamp ? 1 : 0;
      continue;
    }
    const Pose2 d = planarPose(at->inverse() * kf.pose);
    errors.push_back(d.translation().norm());
    yaws.push_back(std::abs(d.theta));
  }
  ASSERT_GE(errors.size(), 10u);
  std::sort(errors.begin(), errors.end());
  std::sort(yaws.begin(), yaws.end());
  std::cout << "[resume_mapping] " << live.size() << " live keyframes, " << errors.size()
            << " on the saved map: median " << errors[errors.size() / 2] << " m, worst "
            << errors.back() << " m, yaw median " << yaws[yaws.size() / 2] * 180.0 / M_PI
            << " deg, worst " << yaws.back() * 180.0 / M_PI << " deg; " << beyond
            << " beyond its end" << std::endl;
  EXPECT_LT(errors[errors.size() / 2], 0.2);
  EXPECT_LT(errors.back(), 0.5);
  // The saved yaw at a stamp is interpolated between keyframes: in a turn that alone is off by
  // degrees (measured worst 2.3 deg).
  EXPECT_LT(yaws[yaws.size() / 2], 0.5 * M_PI / 180.0);
  EXPECT_LT(yaws.back(), 5.0 * M_PI / 180.0);
  EXPECT_GE(beyond, 5u) << "mapped on after the saved map ends";
}

/// Translation errors of `poses` against the saved run at their stamps (sorted), and how many
/// lie after its end.
std::vector<double> errorsAgainstSaved(const Trajectory& saved, const Trajectory& poses,
                                       size_t* beyond) {
  std::vector<double> errors;
  for (const auto& p : poses) {
    if (const auto at = poseAt(saved, p.stamp))
      errors.push_back(planarPose(at->inverse() * p.pose).translation().norm());
    else if (beyond && p.stamp > saved.back().stamp)
      ++*beyond;
  }
  std::sort(errors.begin(), errors.end());
  return errors;
}

TEST(ResumeMapping, TheLocaliserHandsOverToMappingWhereTheDriveLeavesTheMap) {
  if (!R->handover) GTEST_SKIP() << "resume_mapping.test";
  ASSERT_TRUE(R->error.empty()) << R->error;
  const std_msgs::BoolConstPtr mapping =
      ros::topic::waitForMessage<std_msgs::Bool>("slam/mapping", ros::Duration(10.0));
  ASSERT_TRUE(mapping != nullptr) << "no slam/mapping";
  EXPECT_TRUE(mapping->data) << "the drive never left the saved map";
  SaveMap srv;
  srv.request.destination = R->out.string();
  srv.request.resolution = 0.2;
  ASSERT_TRUE(ros::service::call("/graph_backend_test/save_map", srv));
  ASSERT_TRUE(srv.response.success) << srv.response.message;
  std::cout << "[handover] save_map: " << srv.response.message << std::endl;
  EXPECT_NE(srv.response.message.find("handed over by the localiser"), std::string::npos);

  const TrajectoryReadResult saved_read =
      readTumTrajectory((R->saved / "trajectory_tum.txt").string());
  const TrajectoryReadResult merged_read =
      readTumTrajectory((R->out / "trajectory_tum.txt").string());
  ASSERT_TRUE(saved_read.ok && merged_read.ok) << saved_read.error << merged_read.error;
  const Trajectory& saved = saved_read.trajectory;
  const Trajectory live(merged_read.trajectory.begin() + static_cast<std::ptrdiff_t>(saved.size()),
                        merged_read.trajectory.end());
  Trajectory localized;
  {
    std::lock_guard<std::mutex> guard(R->mutex);
    localized = R->localized;
  }
  ASSERT_GE(live.size(), 5u);
  ASSERT_GE(localized.size(), 50u);
  // The drive's poses: the localiser's until the first mapped keyframe, then the keyframes'.
  Trajectory drive;
  for (const auto& p : localized)
    if (p.stamp < live.front().stamp) drive.push_back(p);
  drive.insert(drive.end(), live.begin(), live.end());
  double longest_gap = 0.0;
  for (size_t i = 1; i < drive.size(); ++i)
    longest_gap = std::max(longest_gap, drive[i].stamp - drive[i - 1].stamp);
  size_t beyond = 0;
  const std::vector<double> on_map = errorsAgainstSaved(saved, drive, &beyond);
  ASSERT_GE(on_map.size(), 20u);
  std::cout << "[handover] " << localized.size() << " localised scans, " << live.size()
            << " mapped keyframes (" << beyond << " beyond the saved map) from "
            << live.front().stamp - drive.front().stamp << " s after the first pose; longest gap "
            << longest_gap << " s; on the saved map: median " << on_map[on_map.size() / 2]
            << " m, worst " << on_map.back() << " m" << std::endl;
  // Keyframes are made every 2 m: a gap above 3 s means scans the drive's poses miss.
  EXPECT_LT(longest_gap, 3.0);
  EXPECT_GE(beyond, 5u) << "mapped on after the saved map ends";
  EXPECT_LT(on_map[on_map.size() / 2], 0.2);
  EXPECT_LT(on_map.back(), 0.6);
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  using namespace osm_graph_slam;
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "resume_mapping_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ResumeRun run;
  R = &run;
  R->error = setUp();
  const int rc = RUN_ALL_TESTS();
  std::error_code ec;
  if (rc == 0) fs::remove_all(R->dir, ec);
  spinner.stop();
  ros::shutdown();
  return rc;
}
