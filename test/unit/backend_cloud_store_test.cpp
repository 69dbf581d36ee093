// The back-end keeps its keyframes' clouds in a CloudStore: with everything but the newest
// spilled to disk, the map cloud and save_map hold every keyframe's cloud (lossless by default); a
// corrupt spilled file leaves that one cloud out, says so, and the save still succeeds.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/map_export.h"

namespace osm_graph_slam {
namespace {
namespace fs = std::filesystem;

PointCloudPtr scanAt(int k) {
  std::mt19937 rng(k + 1);
  std::uniform_real_distribution<double> u(-30.0, 30.0), z(-1.5, 5.0);
  auto cloud = std::make_shared<PointCloud>();
  for (int i = 0; i < 3000; ++i) {
    PointT p;
    p.x = static_cast<float>(u(rng));
    p.y = static_cast<float>(u(rng));
    p.z = static_cast<float>(z(rng));
    p.intensity = static_cast<float>(i % 100);
    cloud->push_back(p);
  }
  return cloud;
}

class BackendCloudStore : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("backend_cloud_store_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "store");
    GraphBackendParams params;
    params.use_osm = false;
    params.cloud_store.resident_mb = 0.0;  // every cloud but the newest on disk
    params.cloud_store.directory = (dir_ / "store").string();
    backend_ = std::make_unique<GraphBackend>(
        params, std::make_shared<Logger>([](LogLevel, const std::string&) {}));
    for (int k = 0; k < kKeyframes; ++k) {
      KeyframeInput kf;
      kf.id = k;
      kf.stamp = k;
      kf.odom_pose.translation() = Eigen::Vector3d(2.0 * k, 0.0, 0.0);
      kf.cloud = scanAt(k);
      backend_->addKeyframe(kf);
    }
    backend_->update(true);
  }
  void TearDown() override {
    backend_.reset();
    fs::remove_all(dir_);
  }
  /// The spilled file of keyframe id (the store's folder is the only one in dir_/store).
  fs::path spilledFile(uint64_t id) const {
    for (const auto& d : fs::directory_iterator(dir_ / "store"))
      return d.path() / (std::to_string(id) + ".ogsc");
    return {};
  }

  static constexpr int kKeyframes = 8;
  fs::path dir_;
  std::unique_ptr<GraphBackend> backend_;
};

TEST_F(BackendCloudStore, SpilledCloudsComeBackForTheMapAndTheSave) {
  const CloudStoreStats s = backend_->cloudStoreStats();
  EXPECT_EQ(s.clouds, size_t(kKeyframes));
  EXPECT_EQ(s.resident, 1u);
  EXPECT_EQ(s.on_disk, size_t(kKeyframes - 1));
  EXPECT_LT(s.encoded_bytes * 2, s.pcl_bytes);  // lossless, random points: ~11 of PCL's 32 B

  const std::vector<KeyframeState> keyframes = backend_->keyframes();
  ASSERT_EQ(keyframes.size(), size_t(kKeyframes));
  for (const KeyframeState& kf : keyframes) {
    const PointCloudConstPtr back = kf.cloud.load();
    ASSERT_TRUE(back) << kf.id;
    const PointCloudPtr truth = scanAt(static_cast<int>(kf.id));
    ASSERT_EQ(back->size(), truth->size());
    for (size_t i = 0; i < truth->size(); i += 97)
      EXPECT_EQ((*back)[i].x, (*truth)[i].x) << kf.id;  // the back-end's store is lossless
  }
  EXPECT_EQ(buildMapCloud(keyframes, 0.0)->size(), size_t(kKeyframes * 3000));

  const MapExportResult saved = saveMap(*backend_, (dir_ / "map").string(), 0.2);
  ASSERT_TRUE(saved.success) << saved.message;
  MapPackage package;
  std::string error;
  ASSERT_TRUE(loadMapPackage((dir_ / "map" / "map_package").string(), package, &error)) << error;
  EXPECT_EQ(package.keyframes.size(), size_t(kKeyframes));
  EXPECT_EQ(backend_->cloudStoreStats().read_errors, 0u);
}

TEST_F(BackendCloudStore, ARefusedKeyframeLeavesNoCloudBehind) {
  KeyframeInput duplicate;
  duplicate.id = 3;  // not newer than the last one: refused
  duplicate.cloud = scanAt(99);
  backend_->addKeyframe(duplicate);
  EXPECT_EQ(backend_->cloudStoreStats().clouds, size_t(kKeyframes + 1));  // encoded when queued
  backend_->update();
  EXPECT_EQ(backend_->cloudStoreStats().clouds, size_t(kKeyframes));
  const std::vector<KeyframeState> keyframes = backend_->keyframes();
  EXPECT_EQ(keyframes[3].cloud.load()->points[0].x, scanAt(3)->points[0].x);
}

TEST_F(BackendCloudStore, ACorruptSpilledCloudIsLeftOutAndReported) {
  const fs::path victim = spilledFile(2);
  ASSERT_TRUE(fs::exists(victim)) << victim;
  {
    std::fstream f(victim, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(100);
    f.put('\x55');
  }
  const MapExportResult saved = saveMap(*backend_, (dir_ / "map").string(), 0.2);
  ASSERT_TRUE(saved.success) << saved.message;
  EXPECT_NE(saved.message.find("reads of keyframe clouds failed"), std::string::npos)
      << saved.message;
  EXPECT_NE(saved.message.find("cloud 2"), std::string::npos) << saved.message;
  MapPackage package;
  std::string error;
  ASSERT_TRUE(loadMapPackage((dir_ / "map" / "map_package").string(), package, &error)) << error;
  EXPECT_EQ(package.keyframes.size(), size_t(kKeyframes - 1));

  const MapExportResult dumped = dumpGraph(*backend_, (dir_ / "dump").string());
  ASSERT_TRUE(dumped.success) << dumped.message;
  EXPECT_NE(dumped.message.find("reads of keyframe clouds failed"), std::string::npos);
}

}  // namespace
}  // namespace osm_graph_slam
