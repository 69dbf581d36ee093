// The keyframe cloud codec and store: round trips within the quantisation, spilled clouds read
// back identical, corrupt bytes and files give a clear error for that cloud only.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "osm_graph_slam/cloud/cloud_codec.h"
#include "osm_graph_slam/cloud/cloud_store.h"

namespace osm_graph_slam {
namespace {

// A scan-like cloud: points on rings out to `range`, intensities 0-255.
PointCloud ringCloud(size_t n, double range, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> azimuth(-M_PI, M_PI), r(2.0, range), z(-2.0, 8.0),
      intensity(0.0, 255.0);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    const double a = azimuth(rng), d = r(rng);
    PointT p;
    p.x = static_cast<float>(d * std::cos(a));
    p.y = static_cast<float>(d * std::sin(a));
    p.z = static_cast<float>(z(rng));
    p.intensity = static_cast<float>(intensity(rng));
    cloud.push_back(p);
  }
  cloud.header.frame_id = "base_link";
  cloud.header.stamp = 1234567890123ull;
  return cloud;
}

double maxCoordinateError(const PointCloud& a, const PointCloud& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    worst = std::max({worst, std::abs(double(a[i].x) - b[i].x), std::abs(double(a[i].y) - b[i].y),
                      std::abs(double(a[i].z) - b[i].z)});
  return worst;
}

bool identical(const PointCloud& a, const PointCloud& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].x != b[i].x || a[i].y != b[i].y || a[i].z != b[i].z ||
        a[i].intensity != b[i].intensity)
      return false;
  return true;
}

TEST(CloudCodec, RoundTripsWithinTheQuantisationAndKeepsTheHeader) {
  const PointCloud cloud = ringCloud(20000, 80.0, 1);
  for (int level : {0, 1, 6}) {
    CloudCodecParams params;
    params.deflate_level = level;
    const std::string bytes = encodeCloud(cloud, params);
    std::string error;
    const PointCloudPtr back = decodeCloud(bytes, &error);
    ASSERT_TRUE(back) << error;
    ASSERT_EQ(back->size(), cloud.size());
    EXPECT_LE(maxCoordinateError(cloud, *back), 0.005 + 1e-4);  // half a 1 cm step (+ float)
    double worst_intensity = 0.0;
    for (size_t i = 0; i < cloud.size(); ++i)
      worst_intensity =
          std::max<double>(worst_intensity, std::abs(cloud[i].intensity - (*back)[i].intensity));
    EXPECT_LE(worst_intensity, 255.0 / 65535.0);
    EXPECT_EQ(back->header.frame_id, "base_link");
    EXPECT_EQ(back->header.stamp, cloud.header.stamp);
    EXPECT_DOUBLE_EQ(encodedResolution(bytes), 0.01);
    // 32 bytes a PCL point; 8 before deflate (+ a header).
    EXPECT_LT(bytes.size(), cloud.size() * 8 + 200);
    std::printf("[ codec ] deflate %d: %.2f bytes/point (PCL: %zu)\n", level,
                static_cast<double>(bytes.size()) / cloud.size(), sizeof(PointT));
  }
}

TEST(CloudCodec, ResolutionZeroIsLossless) {
  PointCloud cloud = ringCloud(5000, 80.0, 7);
  cloud[3].x = 1.0e6f;  // any width
  CloudCodecParams params;
  params.resolution = 0.0;
  const std::string bytes = encodeCloud(cloud, params);
  const PointCloudPtr back = decodeCloud(bytes);
  ASSERT_TRUE(back);
  EXPECT_TRUE(identical(cloud, *back));
  EXPECT_LT(bytes.size(), cloud.size() * 16 + 200);
}

TEST(CloudCodec, AWideCloudGetsTheStepThatFitsIt) {
  PointCloud cloud = ringCloud(1000, 80.0, 2);
  cloud[0].x = 1500.0f;  // 1.58 km wide: beyond 65,534 steps of 1 cm
  const std::string bytes = encodeCloud(cloud);
  const double step = encodedResolution(bytes);
  EXPECT_GT(step, 0.01);
  EXPECT_LT(step, 0.03);
  const PointCloudPtr back = decodeCloud(bytes);
  ASSERT_TRUE(back);
  EXPECT_LE(maxCoordinateError(cloud, *back), step / 2 + 1e-3);
}

TEST(CloudCodec, LeavesOutNonFinitePointsAndEncodesAnEmptyCloud) {
  PointCloud cloud = ringCloud(10, 20.0, 3);
  cloud[4].x = std::numeric_limits<float>::quiet_NaN();
  const PointCloudPtr back = decodeCloud(encodeCloud(cloud));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->size(), 9u);
  const PointCloudPtr empty = decodeCloud(encodeCloud(PointCloud()));
  ASSERT_TRUE(empty);
  EXPECT_TRUE(empty->empty());
}

TEST(CloudCodec, CorruptBytesGiveAClearErrorNotACrash) {
  const std::string bytes = encodeCloud(ringCloud(500, 40.0, 4));
  std::string error;
  std::string flipped = bytes;
  flipped[flipped.size() / 2] ^= 0x5a;
  EXPECT_FALSE(decodeCloud(flipped, &error));
  EXPECT_NE(error.find("checksum"), std::string::npos) << error;
  for (size_t keep : {size_t(0), size_t(3), size_t(40), bytes.size() - 1}) {
    error.clear();
    EXPECT_FALSE(decodeCloud(bytes.substr(0, keep), &error)) << keep;
    EXPECT_FALSE(error.empty());
  }
  EXPECT_FALSE(decodeCloud("OGSC" + std::string(100, '\0'), &error));
}

class CloudStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    parent_ =
        std::filesystem::temp_directory_path() /
        ("cloud_store_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(parent_);
  }
  void TearDown() override { std::filesystem::remove_all(parent_); }
  CloudStoreParams params(double resident_mb) const {
    CloudStoreParams p;
    p.resident_mb = resident_mb;
    p.directory = parent_.string();
    return p;
  }
  std::filesystem::path parent_;
};

TEST_F(CloudStoreTest, KeepsTheBudgetAndReadsSpilledCloudsBackIdentical) {
  const size_t clouds = 40;
  std::vector<PointCloudPtr> resident_copies;
  {
    CloudStore store(params(0.25));  // 256 kB: ~7 of these 5k-point clouds (random: ~7 B/point)
    for (size_t id = 0; id < clouds; ++id) {
      store.put(id, ringCloud(5000, 60.0, 100 + id));
      resident_copies.push_back(decodeCloud(store.encoded(id)));  // before any spill
    }
    const CloudStoreStats s = store.stats();
    EXPECT_EQ(s.clouds, clouds);
    EXPECT_LE(s.resident_bytes, 256 * 1024);
    EXPECT_GE(s.resident, 5u);
    EXPECT_LE(s.resident, 8u);
    EXPECT_EQ(s.on_disk, clouds - s.resident);
    EXPECT_EQ(s.write_errors, 0u);
    EXPECT_EQ(s.pcl_bytes, clouds * 5000 * sizeof(PointT));
    ASSERT_FALSE(store.filePath(0).empty());
    for (size_t id = 0; id < clouds; ++id) {
      std::string error;
      const PointCloudConstPtr back = store.get(id, &error);
      ASSERT_TRUE(back) << error;
      EXPECT_TRUE(identical(*back, *resident_copies[id])) << id;
    }
    EXPECT_EQ(store.stats().read_errors, 0u);
    EXPECT_TRUE(std::filesystem::exists(store.directory()));
  }
  // The store's own directory goes with it; the parent stays.
  EXPECT_TRUE(std::filesystem::is_empty(parent_));
}

TEST_F(CloudStoreTest, ACorruptFileFailsThatCloudOnlyWithItsReason) {
  CloudStore store(params(0.0));  // everything but the newest spills
  for (uint64_t id = 0; id < 5; ++id) store.put(id, ringCloud(2000, 30.0, 200 + id));
  const std::string victim = store.filePath(2);
  ASSERT_FALSE(victim.empty());
  {
    std::fstream f(victim, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(60);
    f.put('\x7f');
  }
  std::string error;
  EXPECT_FALSE(store.get(2, &error));
  EXPECT_NE(error.find("cloud 2"), std::string::npos) << error;
  EXPECT_NE(error.find("checksum"), std::string::npos) << error;
  std::filesystem::remove(store.filePath(3));
  EXPECT_FALSE(store.get(3, &error));
  EXPECT_NE(error.find("cannot read"), std::string::npos) << error;
  EXPECT_EQ(store.stats().read_errors, 2u);
  for (uint64_t id : {0, 1, 4}) EXPECT_TRUE(store.get(id)) << id;
  EXPECT_FALSE(store.get(99, &error));  // unknown: not a read error
  EXPECT_EQ(store.stats().read_errors, 2u);
}

TEST_F(CloudStoreTest, AFailedSpillKeepsTheCloudInMemory) {
  std::filesystem::create_directories(parent_);
  std::ofstream(parent_ / "not_a_directory") << "x";
  CloudStoreParams p = params(0.0);
  p.directory = (parent_ / "not_a_directory").string();
  CloudStore store(p);
  for (uint64_t id = 0; id < 3; ++id) store.put(id, ringCloud(1000, 30.0, 300 + id));
  const CloudStoreStats s = store.stats();
  EXPECT_GE(s.write_errors, 1u);
  EXPECT_FALSE(s.last_error.empty());
  EXPECT_EQ(s.resident, 3u);
  for (uint64_t id = 0; id < 3; ++id) EXPECT_TRUE(store.get(id));
}

TEST_F(CloudStoreTest, ReplacingAndErasingKeepTheCountsRight) {
  CloudStore store(params(0.0));
  for (uint64_t id = 0; id < 4; ++id) store.put(id, ringCloud(1000, 30.0, 400 + id));
  store.put(1, ringCloud(300, 30.0, 500));
  store.erase(0);
  const CloudStoreStats s = store.stats();
  EXPECT_EQ(s.clouds, 3u);
  EXPECT_EQ(s.points, 2300u);
  EXPECT_EQ(store.points(1), 300u);
  EXPECT_FALSE(store.contains(0));
  EXPECT_EQ(store.get(1)->size(), 300u);
}

TEST(StoredCloud, HoldsACloudDirectlyOrThroughAStore) {
  const auto cloud = std::make_shared<PointCloud>(ringCloud(100, 10.0, 6));
  const StoredCloud direct(cloud);
  EXPECT_TRUE(direct);
  EXPECT_EQ(direct.load(), cloud);
  EXPECT_FALSE(StoredCloud());
  EXPECT_FALSE(StoredCloud(PointCloudConstPtr()));

  auto store = std::make_shared<CloudStore>();
  const StoredCloud stored(store, 7, cloud);
  EXPECT_TRUE(stored);
  EXPECT_EQ(stored.size(), 100u);
  ASSERT_TRUE(stored.load());
  EXPECT_LE(maxCoordinateError(*cloud, *stored.load()), 0.0051);
  EXPECT_FALSE(StoredCloud(store, 8, nullptr));
}

}  // namespace
}  // namespace osm_graph_slam
