// backendMarkers: one namespace per kind of graph element, so rviz can toggle each.
#include <gtest/gtest.h>

#include <map>

#include "osm_graph_slam/ros/backend_markers.h"

namespace osm_graph_slam {
namespace {

std::map<std::string, const visualization_msgs::Marker*> byNamespace(
    const visualization_msgs::MarkerArray& array) {
  std::map<std::string, const visualization_msgs::Marker*> out;
  for (const auto& m : array.markers)
    if (!m.ns.empty()) out[m.ns] = &m;
  return out;
}

TEST(BackendMarkers, EdgeKindsHaveTheirOwnNamespaces) {
  PoseGraph g;
  g.addVertexSE3(0, Eigen::Isometry3d::Identity());
  Eigen::Isometry3d second = Eigen::Isometry3d::Identity();
  second.translation().x() = 2.0;
  g.addVertexSE3(1, second);
  g.addVertexSE2(100, Pose2(5.0, 7.0, 0.0));
  g.addVertexSE2(101, Pose2(15.0, 7.0, M_PI / 2));
  g.addEdgeSE3(0, 1, second, Matrix6d::Identity());
  g.addEdgeSE3SE2(1, 100, Pose2(3.0, 7.0, 0.0), Eigen::Matrix3d::Identity(), {1, {}});
  // Building 100's wall end at (10, 0) in its frame lies on building 101's wall.
  g.addEdgeSE2PointOnLine(100, 101, Eigen::Vector2d(10.0, 0.0), Eigen::Vector2d(0, 1), 0.0, 25.0,
                          {1, {}});
  g.addEdgeSE2(100, 101, Pose2(10.0, 0.0, M_PI / 2), Eigen::Matrix3d::Identity(), {2, {}});
  std_msgs::Header header;
  header.frame_id = "map";
  const visualization_msgs::MarkerArray array = backendMarkers(g, {}, {}, header);
  const auto markers = byNamespace(array);
  ASSERT_TRUE(markers.count("edges_level0_robot"));
  EXPECT_EQ(markers.at("edges_level0_robot")->points.size(), 2u);
  ASSERT_TRUE(markers.count("edges_level1_robot_building"));
  EXPECT_EQ(markers.at("edges_level1_robot_building")->points.size(), 2u)
      << "the shared wall is not drawn as a robot<->building edge";
  ASSERT_TRUE(markers.count("edges_level1_shared_wall"));
  const auto& post = markers.at("edges_level1_shared_wall")->points;
  ASSERT_EQ(post.size(), 2u);
  EXPECT_DOUBLE_EQ(post[0].x, 15.0);
  EXPECT_DOUBLE_EQ(post[0].y, 7.0);
  EXPECT_GT(post[1].z, post[0].z);
  EXPECT_EQ(markers.at("edges_level2_building_building")->points.size(), 2u);
}

}  // namespace
}  // namespace osm_graph_slam
