// Regression tests for what the libFuzzer targets of fuzz/ found (issue 22, doc/reliability.md).
// Each case is the minimised input of a crash or sanitizer report; the reader must now refuse it
// (or read it) cleanly. Under scripts/test.sh --sanitize these run with ASan + UBSan as well.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "osm_graph_slam/io/kitti_raw.h"

namespace osm_graph_slam {
namespace {

/// A file in a fresh temporary directory, removed with the fixture.
class FuzzRegression : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("ogs_fuzz_regression_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& content) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << content;
    return path;
  }
  std::filesystem::path dir_;
};

// fuzz_kitti: "0011-09-26 13:02:25.96" (year 11) and years beyond 2262 overflowed int64
// nanoseconds (signed overflow, UBSan). Stamps before 1970 or after 2261 are refused now.
TEST_F(FuzzRegression, KittiTimestampOutsideTheInt64NanosecondRangeIsRefused) {
  StampNs stamp = 42;
  EXPECT_FALSE(parseKittiTimestamp("011-09-26 13:02:25.96 ", stamp));
  EXPECT_FALSE(parseKittiTimestamp("292277026596-12-04 15:30:07.5", stamp));
  EXPECT_FALSE(parseKittiTimestamp("1969-12-31 23:59:59.0", stamp));
  EXPECT_FALSE(parseKittiTimestamp("2262-04-11 23:47:16.9", stamp));
  EXPECT_FALSE(parseKittiTimestamp("2011-09-26 -1:02:25.0", stamp));
  EXPECT_EQ(stamp, 42);
  ASSERT_TRUE(parseKittiTimestamp("2261-12-31 23:59:59.999999999", stamp));
  EXPECT_EQ(formatKittiTimestamp(stamp), "2261-12-31 23:59:59.999999999");
  ASSERT_TRUE(parseKittiTimestamp("1970-01-01 00:00:00.000000001", stamp));
  EXPECT_EQ(stamp, 1);
  std::vector<StampNs> stamps;
  std::string error;
  EXPECT_FALSE(readKittiTimestamps(write("timestamps.txt",
                                         "2011-09-26 13:02:25.964389445\n"
                                         "0011-09-26 13:02:25.96\n"),
                                   stamps, &error));
  EXPECT_NE(error.find("line 2"), std::string::npos) << error;
}

}  // namespace
}  // namespace osm_graph_slam
