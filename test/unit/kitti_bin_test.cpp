#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "osm_graph_slam/io/kitti_bin.h"
#include "test_data.h"

using namespace osm_graph_slam;

TEST(KittiBin, ReadsRealScanWithPlausibleContent) {
  const std::string path = test::sharedDataPath("kitti00/000094.bin");
  OGS_REQUIRE_SHARED_FILE(path);
  PointCloud cloud;
  std::string error;
  ASSERT_TRUE(readKittiBin(path, cloud, &error)) << error;
  EXPECT_GT(cloud.size(), 100000u);  // ~122k points per HDL-64E scan
  EXPECT_LT(cloud.size(), 140000u);
  double max_range = 0.0;
  for (const auto& p : cloud) max_range = std::max(max_range, std::hypot(double(p.x), double(p.y)));
  EXPECT_GT(max_range, 50.0);
  EXPECT_LT(max_range, 130.0);
}

TEST(KittiBin, WriteReadRoundTripIsBitExact) {
  PointCloud cloud;
  for (int i = 0; i < 100; ++i) {
    PointT p;
    p.x = 0.1f * i;
    p.y = -0.37f * i;
    p.z = 1e-7f * i;
    p.intensity = 0.01f * i;
    cloud.push_back(p);
  }
  const std::string path = ::testing::TempDir() + "/roundtrip.bin";
  ASSERT_TRUE(writeKittiBin(path, cloud));
  PointCloud back;
  ASSERT_TRUE(readKittiBin(path, back));
  ASSERT_EQ(back.size(), cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    EXPECT_EQ(back[i].x, cloud[i].x);
    EXPECT_EQ(back[i].intensity, cloud[i].intensity);
  }
  std::remove(path.c_str());
}

TEST(KittiBin, RejectsMissingAndTruncatedFiles) {
  PointCloud cloud;
  std::string error;
  EXPECT_FALSE(readKittiBin("/nonexistent/scan.bin", cloud, &error));
  EXPECT_NE(error.find("cannot open"), std::string::npos);
  const std::string path = ::testing::TempDir() + "/truncated.bin";
  std::ofstream(path, std::ios::binary) << "0123456789";  // 10 bytes
  EXPECT_FALSE(readKittiBin(path, cloud, &error));
  EXPECT_NE(error.find("multiple of 16"), std::string::npos);
  std::remove(path.c_str());
}
