// rostest for the osm_buffer nodelet: origin from the first valid fix, buildings around the
// pose from the local Overpass test server (real Karlsruhe extract), markers, refill on motion.
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <nodelet/NodeletLoad.h>
#include <nodelet/NodeletUnload.h>
#include <ros/ros.h>
#include <sensor_msgs/NavSatFix.h>

#include <mutex>
#include <set>

#include "osm_graph_slam/osm/osm_buffer.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/ros/osm_conversions.h"
#include "overpass_server_fixture.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

constexpr double kLat0 = 49.0111, kLon0 = 8.4240;
const std::string kOsm = "osm/2011_09_26_drive_0005_sync.osm";

struct Inbox {
  std::mutex mutex;
  sensor_msgs::NavSatFix::ConstPtr origin;
  BuildingArray::ConstPtr buildings;
  visualization_msgs::MarkerArray::ConstPtr markers;
  int origin_count = 0;
};

/// Expected ids: outline within radius of p, from the file read independently of the server.
std::set<int64_t> expectedIds(const std::vector<Building>& all, const Eigen::Vector2d& p,
                              double r) {
  std::set<int64_t> ids;
  for (const Building& b : all) {
    if (outlineDistance(b.outline_enu, p) <= r) ids.insert(b.id);
  }
  return ids;
}

template <typename Pred>
bool spinUntil(Pred pred, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::spinOnce();
    if (pred()) return true;
    ros::WallDuration(0.02).sleep();
  }
  return false;
}

TEST(OsmBufferNodelet, OriginBuildingsAndMarkers) {
  const std::string osm = test::sharedDataPath(kOsm);
  OGS_REQUIRE_SHARED_FILE(osm);
  test::OverpassTestServer server(test::sourceDir() + "/scripts/overpass_test_server.py", osm);
  ASSERT_TRUE(server.start());

  ros::NodeHandle nh, pnh("~");
  std::string manager = "/osm_manager", nodelet_name = "/osm_buffer";
  pnh.param("manager", manager, manager);
  pnh.param("nodelet_name", nodelet_name, nodelet_name);
  nh.setParam(nodelet_name + "/source", "overpass");
  nh.setParam(nodelet_name + "/overpass_url", server.url());
  nh.setParam(nodelet_name + "/overpass_max_retries", 0);
  nh.setParam(nodelet_name + "/retry_initial", 0.2);
  double query_radius = 0.0;
  ASSERT_TRUE(nh.getParam(nodelet_name + "/query_radius", query_radius))
      << "config/osm_buffer.yaml not loaded";

  Inbox inbox;
  auto origin_sub = nh.subscribe<sensor_msgs::NavSatFix>(
      "osm/origin", 1, [&](const sensor_msgs::NavSatFix::ConstPtr& m) {
        std::lock_guard<std::mutex> l(inbox.mutex);
        inbox.origin = m;
        ++inbox.origin_count;
      });
  auto buildings_sub =
      nh.subscribe<BuildingArray>("osm/buildings", 5, [&](const BuildingArray::ConstPtr& m) {
        std::lock_guard<std::mutex> l(inbox.mutex);
        inbox.buildings = m;
      });
  auto markers_sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "osm/markers", 5, [&](const visualization_msgs::MarkerArray::ConstPtr& m) {
        std::lock_guard<std::mutex> l(inbox.mutex);
        inbox.markers = m;
      });
  auto fix_pub = nh.advertise<sensor_msgs::NavSatFix>("gps/fix", 5);
  auto pose_pub = nh.advertise<geometry_msgs::PoseStamped>("slam/pose", 5);

  ASSERT_TRUE(ros::service::waitForService(manager + "/load_nodelet", ros::Duration(30.0)));
  nodelet::NodeletLoad load;
  load.request.name = nodelet_name;
  load.request.type = "osm_graph_slam/OsmBufferNodelet";
  ASSERT_TRUE(ros::service::call(manager + "/load_nodelet", load));
  ASSERT_TRUE(load.response.success);
  ASSERT_TRUE(spinUntil(
      [&] { return fix_pub.getNumSubscribers() > 0 && pose_pub.getNumSubscribers() > 0; }, 20.0));

  // No origin yet: an invalid fix (no fix status) must not set it.
  sensor_msgs::NavSatFix fix;
  fix.header.frame_id = "gps";
  fix.status.status = sensor_msgs::NavSatStatus::STATUS_NO_FIX;
  fix.latitude = 10.0;
  fix.longitude = 10.0;
  fix_pub.publish(fix);
  EXPECT_FALSE(spinUntil([&] { return inbox.origin_count > 0; }, 1.5));

  fix.status.status = sensor_msgs::NavSatStatus::STATUS_FIX;
  fix.latitude = kLat0;
  fix.longitude = kLon0;
  fix.altitude = 115.0;
  fix.header.stamp = ros::Time::now();
  fix_pub.publish(fix);
  ASSERT_TRUE(spinUntil([&] { return inbox.origin_count > 0; }, 10.0));
  EXPECT_DOUBLE_EQ(inbox.origin->latitude, kLat0);
  EXPECT_DOUBLE_EQ(inbox.origin->longitude, kLon0);
  EXPECT_EQ(inbox.origin->header.frame_id, "map");
  // A later fix must not move the origin.
  fix.latitude += 0.001;
  fix_pub.publish(fix);

  const OsmData data = readOsmFile(osm);
  ASSERT_TRUE(data.ok);
  const EnuConverter enu(kLat0, kLon0, 115.0);
  std::vector<Building> all = data.buildings;
  for (Building& b : all) enu.project(b);

  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(40, 5), Eigen::Vector2d(90, 10)}) {
    geometry_msgs::PoseStamped pose;
    pose.header.frame_id = "map";
    pose.pose.position.x = p.x();
    pose.pose.position.y = p.y();
    pose.pose.orientation.w = 1.0;
    const std::set<int64_t> expected = expectedIds(all, p, query_radius);
    ASSERT_FALSE(expected.empty());
    std::set<int64_t> got;
    const bool arrived = spinUntil(
        [&] {
          pose.header.stamp = ros::Time::now();
          pose_pub.publish(pose);
          std::lock_guard<std::mutex> l(inbox.mutex);
          if (!inbox.buildings || std::hypot(inbox.buildings->query_center.x - p.x(),
                                             inbox.buildings->query_center.y - p.y()) > 1e-6) {
            return false;
          }
          got.clear();
          for (const auto& b : inbox.buildings->buildings) got.insert(b.id);
          return got == expected;
        },
        30.0);
    EXPECT_TRUE(arrived) << "at " << p.transpose() << ": got " << got.size()
                         << " buildings, expected " << expected.size();
    std::lock_guard<std::mutex> l(inbox.mutex);
    ASSERT_TRUE(inbox.buildings);
    EXPECT_EQ(inbox.buildings->header.frame_id, "map");
    EXPECT_DOUBLE_EQ(inbox.buildings->query_radius, query_radius);
    for (const auto& m : inbox.buildings->buildings) {
      EXPECT_EQ(m.segments.size(), m.outline.size());
      EXPECT_EQ(m.tag_keys.size(), m.tag_values.size());
      double lowest = 1e9;
      for (const auto& v : m.outline) lowest = std::min(lowest, v.x);
      EXPECT_NEAR(m.reference_pose.x, lowest, 1e-3);
    }
  }
  EXPECT_TRUE(spinUntil([&] { return inbox.markers != nullptr; }, 5.0));
  {
    std::lock_guard<std::mutex> l(inbox.mutex);
    ASSERT_TRUE(inbox.markers);
    ASSERT_EQ(inbox.markers->markers.size(), 3u);
    EXPECT_EQ(inbox.markers->markers[0].action, visualization_msgs::Marker::DELETEALL);
    EXPECT_EQ(inbox.markers->markers[1].points.size() % 2, 0u);
  }
  EXPECT_EQ(inbox.origin_count, 1);
  EXPECT_DOUBLE_EQ(inbox.origin->latitude, kLat0);
  // (90, 10) is more than 60 m from the first buffer: a refill happened.
  EXPECT_GE(server.get("/stats").find("\"answered\": 2") != std::string::npos ||
                server.get("/stats").find("\"answered\": 3") != std::string::npos,
            true)
      << server.get("/stats");

  nodelet::NodeletUnload unload;
  unload.request.name = nodelet_name;
  ros::service::call(manager + "/unload_nodelet", unload);
  server.stop();
}

}  // namespace
}  // namespace osm_graph_slam

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "osm_buffer_rostest");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
