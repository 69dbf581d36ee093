// Rostest node for frontend_dropout.test (issue 19): the front-end nodelets keep tracking and
// publishing keyframes through a dropout of the sensor. Three front-ends run side by side
// (namespaces reference, gap5, gap20; launch/frontend.launch each). The node writes a bag of 60
// consecutive real KITTI raw 0005 scans (40..99, velo_link, 10 Hz stamps) with the rosbag C++
// API and plays it into each in lock-step: all of it into `reference`, and with 5 scans left out
// (a 0.6 s hole in the stamps) into `gap5`, with 20 left out (2.1 s, through the turn's yaw-rate
// reversal) into `gap20`. The odometry after a gap must stay on the gapless one, keyframes must
// keep coming, and the status and the rviz label must say ok / recovered, never lost.
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <unistd.h>
#include <visualization_msgs/Marker.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/ScanMatchingStatus.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/ros/conversions.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

constexpr int kFirstScan = 40;  // the turn of drive 0005 (0.7-1.1 deg per scan, ~3.6 m/s)
constexpr int kScans = 60;      // scans 40..99
constexpr const char* kSensorFrame = "velo_link";

/// A front-end under test: its namespace, the scans (window indices) left out, and what it must
/// still do after the gap.
struct Case {
  std::string ns;
  int gap_first = -1, gap_scans = 0;  ///< window indices [gap_first, gap_first + gap_scans)
  size_t min_keyframes_after = 0;     ///< keyframes after the gap, at least
  size_t max_failed = 0;              ///< failed matches, at most
  /// [m] error of the scans after the gap against the gapless run, at most. The first scan after
  /// a hole cannot know its own velocity, so it is deskewed by the mean motion across the hole
  /// (doc/frontend.md); across gap20's yaw-rate reversal that leaves it 0.13 m off (measured).
  double max_err_t = 0.085;
  bool dropped(int k) const { return k >= gap_first && k < gap_first + gap_scans; }
  int firstAfterGap() const { return gap_first + gap_scans; }
};

const Case kReference{"reference"};
// Drive scans 58..62 left out: 57 -> 63, a 0.6 s hole (2.1 m).
const Case kGap5{"gap5", 18, 5, 6, 1};
// Drive scans 55..74 left out: 54 -> 75, a 2.1 s hole (8.5 m) across the turn's yaw-rate reversal
// (+0.85 to -1.1 deg per scan), so the constant-velocity guess across it is ~20 deg off.
const Case kGap20{"gap20", 15, 20, 4, 5, 0.2};

struct Received {
  std::mutex mutex;
  std::vector<nav_msgs::Odometry> odom;
  std::vector<KeyFrame> keyframes;
  std::vector<ScanMatchingStatus> status;
  std::vector<visualization_msgs::Marker> markers;
};

bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.01).sleep();
  }
  return done();
}

/// The front-end of one namespace: subscriptions recording everything it publishes.
class FrontEnd {
 public:
  FrontEnd(ros::NodeHandle& nh, const std::string& ns) {
    odom_sub_ = nh.subscribe<nav_msgs::Odometry>(ns + "/odom", 100,
                                                 [this](const nav_msgs::OdometryConstPtr& m) {
                                                   std::lock_guard<std::mutex> lock(rx.mutex);
                                                   rx.odom.push_back(*m);
                                                 });
    kf_sub_ = nh.subscribe<KeyFrame>(ns + "/keyframe", 100, [this](const KeyFrameConstPtr& m) {
      std::lock_guard<std::mutex> lock(rx.mutex);
      KeyFrame k = *m;
      k.cloud.data.clear();  // only the metadata is checked
      rx.keyframes.push_back(k);
    });
    status_sub_ = nh.subscribe<ScanMatchingStatus>(ns + "/scan_matching_status", 100,
                                                   [this](const ScanMatchingStatusConstPtr& m) {
                                                     std::lock_guard<std::mutex> lock(rx.mutex);
                                                     rx.status.push_back(*m);
                                                   });
    marker_sub_ = nh.subscribe<visualization_msgs::Marker>(
        ns + "/tracking_health_marker", 100, [this](const visualization_msgs::MarkerConstPtr& m) {
          std::lock_guard<std::mutex> lock(rx.mutex);
          rx.markers.push_back(*m);
        });
    pub_ = nh.advertise<sensor_msgs::PointCloud2>(ns + "/velodyne_points", 5);
  }

  bool connected() const {
    return pub_.getNumSubscribers() > 0 && odom_sub_.getNumPublishers() > 0 &&
           status_sub_.getNumPublishers() > 0 && kf_sub_.getNumPublishers() > 0 &&
           marker_sub_.getNumPublishers() > 0;
  }

  size_t statusCount() {
    std::lock_guard<std::mutex> lock(rx.mutex);
    return rx.status.size();
  }

  /// Publishes one scan and waits until the scan matcher reported it.
  bool play(const sensor_msgs::PointCloud2ConstPtr& scan) {
    const size_t before = statusCount();
    pub_.publish(scan);
    return waitFor([&] { return statusCount() > before; }, 120.0);
  }

  Received rx;

 private:
  ros::Subscriber odom_sub_, kf_sub_, status_sub_, marker_sub_;
  ros::Publisher pub_;
};

/// Writes the window as a bag on /velodyne_points: scan k at start + 0.1 k s, in velo_link.
void writeBag(const std::string& path, const std::vector<std::string>& scans,
              const ros::Time& start) {
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  for (int k = 0; k < int(scans.size()); ++k) {
    PointCloud cloud;
    ASSERT_TRUE(readKittiBin(scans[k], cloud)) << scans[k];
    sensor_msgs::PointCloud2 msg;
    toPointCloud2(cloud, msg);
    msg.header.frame_id = kSensorFrame;
    msg.header.stamp = start + ros::Duration(0.1 * k);
    msg.header.seq = k;
    bag.write("/velodyne_points", msg.header.stamp, msg);
  }
  bag.close();
}

double rotationDeg(const Eigen::Isometry3d& t) {
  return Eigen::AngleAxisd(t.linear()).angle() * 180.0 / M_PI;
}

/// What a gap case gave after its gap, against the gapless reference at the same stamps.
struct AfterGap {
  size_t scans = 0;
  double max_err_t = 0.0, max_err_deg = 0.0;  ///< over every scan after the gap
  double first_err_t = 0.0;                   ///< the first scan after the gap
  double final_err_t = 0.0, final_err_deg = 0.0;
  double travelled = 0.0;  ///< reference distance from the last scan before the gap to the end
  size_t keyframes = 0, reference_keyframes = 0;
};

AfterGap compare(Received& rx, Received& ref, const ros::Time& gap_end) {
  std::map<ros::Time, Eigen::Isometry3d> reference;
  for (const auto& o : ref.odom) reference[o.header.stamp] = fromPoseMsg(o.pose.pose);
  AfterGap a;
  std::optional<Eigen::Isometry3d> before_gap;
  for (const auto& o : rx.odom) {
    if (o.header.stamp < gap_end) {
      before_gap = fromPoseMsg(o.pose.pose);
      continue;
    }
    const auto it = reference.find(o.header.stamp);
    if (it == reference.end()) {
      ADD_FAILURE() << "no reference pose at " << o.header.stamp;
      continue;
    }
    const Eigen::Isometry3d err = it->second.inverse() * fromPoseMsg(o.pose.pose);
    const double et = err.translation().norm(), er = rotationDeg(err);
    if (a.scans == 0) a.first_err_t = et;
    a.max_err_t = std::max(a.max_err_t, et);
    a.max_err_deg = std::max(a.max_err_deg, er);
    a.final_err_t = et, a.final_err_deg = er;
    ++a.scans;
  }
  if (before_gap && !ref.odom.empty())
    a.travelled =
        (fromPoseMsg(ref.odom.back().pose.pose).translation() - before_gap->translation()).norm();
  for (const auto& k : rx.keyframes) a.keyframes += k.header.stamp >= gap_end;
  for (const auto& k : ref.keyframes) a.reference_keyframes += k.header.stamp >= gap_end;
  return a;
}

class FrontendDropout : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("ogs_frontend_dropout_" + std::to_string(::getpid()));
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path dir_;
};
fs::path FrontendDropout::dir_;

TEST_F(FrontendDropout, KeyframesAndOdometryContinueThroughTheGap) {
  const std::string archive = test::sharedDataPath("kitti_raw_0005/velodyne.tar.xz");
  const std::string calib = test::sharedDataPath("kitti_raw_0005/calib_2011_09_26.txt");
  OGS_REQUIRE_SHARED_FILE(archive);
  OGS_REQUIRE_SHARED_FILE(calib);
  const ros::WallTime t0 = ros::WallTime::now();

  ros::NodeHandle nh;
  FrontEnd reference(nh, kReference.ns), gap5(nh, kGap5.ns), gap20(nh, kGap20.ns);
  const std::vector<std::pair<const Case*, FrontEnd*>> cases = {
      {&kReference, &reference}, {&kGap5, &gap5}, {&kGap20, &gap20}};

  // The KITTI mounting: base_link is the OXTS unit (as kitti2bag and offline_slam --calib).
  Eigen::Isometry3d velo_from_imu;
  std::string error;
  ASSERT_TRUE(readKittiTrackingCalib(calib, "Tr_imu_to_velo", velo_from_imu, &error)) << error;
  tf2_ros::StaticTransformBroadcaster static_tf;
  geometry_msgs::TransformStamped mount;
  mount.header.stamp = ros::Time::now();
  mount.header.frame_id = "base_link";
  mount.child_frame_id = kSensorFrame;
  mount.transform = toTransformMsg(velo_from_imu.inverse());
  static_tf.sendTransform(mount);
  ros::AsyncSpinner spinner(2);
  spinner.start();

  const std::vector<std::string> scans =
      test::unpackKitti0005Scans(dir_ / "kitti_raw_0005", kFirstScan, kScans, &error);
  ASSERT_EQ(scans.size(), size_t(kScans)) << error;
  const std::string bag_path = (dir_ / "kitti_raw_0005.bag").string();
  const ros::Time start = ros::Time::now();
  writeBag(bag_path, scans, start);
  fs::remove_all(dir_ / "kitti_raw_0005");
  const double prepare_s = (ros::WallTime::now() - t0).toSec();

  ASSERT_TRUE(waitFor(
      [&] {
        return std::all_of(cases.begin(), cases.end(),
                           [](auto& c) { return c.second->connected(); });
      },
      60.0))
      << "the three front-ends did not come up";

  // Lock-step replay of the bag into each front-end, leaving out the case's gap.
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  for (const auto& [c, frontend] : cases) {
    int k = 0;
    for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
      const auto msg = m.instantiate<sensor_msgs::PointCloud2>();
      ASSERT_TRUE(msg);
      if (!c->dropped(k++)) {
        ASSERT_TRUE(frontend->play(msg)) << c->ns << ": no status for scan " << k - 1;
      }
    }
  }
  bag.close();
  ros::WallDuration(0.3).sleep();  // the last keyframes and markers
  const double play_s = (ros::WallTime::now() - t0).toSec() - prepare_s;

  std::lock_guard<std::mutex> lock_ref(reference.rx.mutex);
  Received& ref = reference.rx;
  ASSERT_EQ(ref.odom.size(), size_t(kScans));
  for (const auto& s : ref.status) EXPECT_FALSE(s.failed) << "reference: " << s.message;
  // The reference itself: frontend_demo on the same scans (velo_link as base) goes 24.6 m and
  // turns -20.6 deg in yaw from scan 40 to 99 (left by 19 deg, then right by 40 deg).
  const Eigen::Isometry3d ref_end = fromPoseMsg(ref.odom.back().pose.pose);
  std::printf("[frontend_dropout] reference: %zu keyframes, %.2f m, %.1f deg over %d scans\n",
              ref.keyframes.size(), ref_end.translation().norm(), rotationDeg(ref_end), kScans);
  EXPECT_NEAR(ref_end.translation().norm(), 24.6, 1.0);
  EXPECT_NEAR(rotationDeg(ref_end), 20.6, 1.5);

  for (const auto& [c, frontend] : cases) {
    if (c == &kReference) continue;
    SCOPED_TRACE(c->ns);
    std::lock_guard<std::mutex> lock(frontend->rx.mutex);
    Received& rx = frontend->rx;
    const size_t sent = size_t(kScans - c->gap_scans);
    const ros::Time gap_end = start + ros::Duration(0.1 * c->firstAfterGap());
    ASSERT_EQ(rx.status.size(), sent);
    ASSERT_EQ(rx.odom.size(), sent) << "every scan gets an odometry pose, matched or predicted";

    // Odometry after the gap stays on the gapless run.
    const AfterGap a = compare(rx, ref, gap_end);
    // Tracking health: never lost for these gaps, failures counted one per failed status;
    // counted over the scans and asserted once each (a broken run would fail on every scan).
    size_t failed = 0, recovered = 0, not_ok = 0, lost_events = 0, miscounted = 0;
    double max_since_keyframe = 0.0;
    std::string first_not_ok;
    for (const auto& s : rx.status) {
      failed += s.failed;
      recovered += s.tracking_state == "recovered";
      if (s.tracking_state != "ok" && s.tracking_state != "recovered" && not_ok++ == 0)
        first_not_ok = s.tracking_state + ": " + s.message;
      lost_events = std::max<size_t>(lost_events, s.lost_events);
      miscounted += s.failed_matches != failed;
      max_since_keyframe = std::max(max_since_keyframe, s.time_since_keyframe);
    }
    EXPECT_EQ(not_ok, 0u) << "first: " << first_not_ok;
    EXPECT_EQ(lost_events, 0u);
    EXPECT_EQ(miscounted, 0u) << "failed_matches must count the failed statuses";
    // A keyframe at least every keyframe_delta_time (2 s, + one scan) while tracking, the hole
    // added.
    EXPECT_LT(max_since_keyframe, 0.1 * (c->gap_scans + 1) + 2.15);
    const ScanMatchingStatus& first_after = rx.status[size_t(c->gap_first)];
    std::printf(
        "[frontend_dropout] %s: hole %.1f s; first scan after it: %s (fitness %.3f); after the "
        "gap %zu scans, %.2f m travelled: error vs gapless max %.3f m / %.3f deg, first %.3f m, "
        "final %.3f m / %.3f deg; keyframes after %zu (gapless %zu), at most %.1f s apart; failed "
        "%zu, recovered %zu; markers %zu\n",
        c->ns.c_str(), 0.1 * (c->gap_scans + 1), first_after.message.c_str(), first_after.fitness,
        a.scans, a.travelled, a.max_err_t, a.max_err_deg, a.first_err_t, a.final_err_t,
        a.final_err_deg, a.keyframes, a.reference_keyframes, max_since_keyframe, failed, recovered,
        rx.markers.size());
    EXPECT_EQ(a.scans, size_t(kScans - c->firstAfterGap()));
    EXPECT_GT(a.travelled, 10.0);
    // Measured 2.8 / 2.4 cm and 0.052 / 0.039 deg (gap5 / gap20, deterministic); ~3x that.
    // With deskewing: 2.8 / 13.0 cm (the first scan after the hole), final 1.7 / 5.4 cm,
    // 0.090 / 0.137 deg.
    EXPECT_LT(a.max_err_t, c->max_err_t);
    EXPECT_LT(a.final_err_t, 0.085);
    EXPECT_LT(a.max_err_deg, 0.16);
    // Keyframes keep coming after the gap, as many as without it (+-1: the gap moves them).
    EXPECT_GE(a.keyframes, c->min_keyframes_after);
    EXPECT_GE(a.keyframes + 1, a.reference_keyframes);
    EXPECT_LE(a.keyframes, a.reference_keyframes + 1);
    EXPECT_LE(failed, c->max_failed);
    ASSERT_FALSE(rx.keyframes.empty());
    for (size_t i = 1; i < rx.keyframes.size(); ++i)
      EXPECT_EQ(rx.keyframes[i].id, rx.keyframes[i - 1].id + 1);

    // The rviz label: first "OK", never "LOST", green when OK, above base_link.
    ASSERT_FALSE(rx.markers.empty());
    EXPECT_EQ(rx.markers.front().text, "tracking: OK");
    for (const auto& m : rx.markers) {
      EXPECT_EQ(m.header.frame_id, "base_link");
      EXPECT_EQ(m.type, visualization_msgs::Marker::TEXT_VIEW_FACING);
      EXPECT_EQ(m.text.find("LOST"), std::string::npos) << m.text;
      if (m.text == "tracking: OK") {
        EXPECT_GT(m.color.g, 0.8f);
      }
    }
    // Published with each keyframe (and on changes), not with every scan.
    EXPECT_GE(rx.markers.size(), rx.keyframes.size());
    EXPECT_LT(rx.markers.size(), sent / 2);
  }
  std::printf("[frontend_dropout] prepare %.1f s (unpack, bag), play %.1f s (%d scans)\n",
              prepare_s, play_s, 3 * kScans - kGap5.gap_scans - kGap20.gap_scans);
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "frontend_dropout_test");
  ros::NodeHandle nh;  // keep the node alive for the whole run
  return RUN_ALL_TESTS();
}
