#include <gtest/gtest.h>

#include <pcl/io/pcd_io.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "map_server_reader.h"
#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/map_server_files.h"
#include "osm_graph_slam/localization/map_package.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/grid_map.h"
#include "osm_graph_slam/slam/map_export.h"
#include "street_drive.h"

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

struct ExportFixture : ::testing::Test {
  static void SetUpTestSuite() {
    drive_ = new test::StreetDrive(12, 2.5, true);
    GraphBackendParams params;
    params.initial_yaw_known = true;
    params.initial_yaw = drive_->true_poses[0].theta;
    backend_ = new GraphBackend(params);
    backend_->setOrigin(49.0, 8.4, 110.0);
    const EnuConverter enu(49.0, 8.4, 110.0);
    std::vector<Building> prior = drive_->truth;
    for (auto& b : prior)
      for (const auto& v : b.outline_enu) b.outline_geo.push_back(enu.toGeoPoint(v));
    prior[0].tags = {{"building", "yes"}, {"name", "A & B <quoted>"}};
    drive_->feed(*backend_, drive_->odometry(0.0, 1.0), prior);
    LoopClosureInput loop;
    loop.from_id = 11;
    loop.to_id = 2;
    loop.relative_pose =
        isometryFromPlanar(drive_->true_poses[2].inverse() * drive_->true_poses[11]);
    backend_->addLoopClosure(loop);
    // Flat ground 1.73 m below every other keyframe's base_link, slightly tilted.
    for (uint64_t k = 0; k < 12; k += 2)
      backend_->addFloor(k, Eigen::Vector4d(0.01, -0.005, 1.0, 1.73).normalized());
    backend_->update();
  }
  static void TearDownTestSuite() {
    delete backend_;
    delete drive_;
  }
  std::string tempDir(const std::string& name) const {
    const fs::path dir = fs::path(::testing::TempDir()) / name;
    fs::remove_all(dir);
    return dir.string();
  }
  static test::StreetDrive* drive_;
  static GraphBackend* backend_;
};

/// Every regular file below dir, by relative path, with its content.
std::map<std::string, std::string> folderContents(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::ifstream in(e.path(), std::ios::binary);
    std::ostringstream content;
    content << in.rdbuf();
    files[fs::relative(e.path(), dir).string()] = content.str();
  }
  return files;
}

/// A full disk for this process: writes past `bytes` per file fail with EFBIG (a file-size limit
/// works for root too, where a read-only folder would not). Restored on destruction.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    previous_handler_ = std::signal(SIGXFSZ, SIG_IGN);  // else the write kills the process
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    std::signal(SIGXFSZ, previous_handler_);
  }

 private:
  rlimit saved_{};
  void (*previous_handler_)(int) = SIG_DFL;
};
test::StreetDrive* ExportFixture::drive_ = nullptr;
GraphBackend* ExportFixture::backend_ = nullptr;

}  // namespace

TEST_F(ExportFixture, SaveMapWritesFilesThatParse) {
  const std::string dir = tempDir("save_map");
  const MapExportResult r = saveMap(*backend_, dir, 0.2);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.files.size(), 10u);  // with graph/ and map.pgm + map.yaml (grid_enabled)
  for (const auto& f : r.files) EXPECT_TRUE(fs::exists(f)) << f;
  // The map package for localisation loads back with every keyframe.
  MapPackage package;
  std::string error;
  ASSERT_TRUE(loadMapPackage(dir + "/map_package", package, &error)) << error;
  EXPECT_EQ(package.keyframes.size(), backend_->keyframes().size());
  for (const auto& entry : fs::directory_iterator(dir)) {
    EXPECT_NE(entry.path().extension(), ".tmp") << "temporary file left behind";
    EXPECT_NE(entry.path().filename().string().rfind(".partial", 0), 0u) << "staging left behind";
  }

  PointCloud map;
  ASSERT_EQ(pcl::io::loadPCDFile(dir + "/map.pcd", map), 0);
  const PointCloudPtr built = buildMapCloud(backend_->keyframes(), 0.2);
  ASSERT_EQ(map.size(), built->size());
  for (size_t i = 0; i < map.size(); i += 97) {  // our binary writer against PCL's reader
    EXPECT_EQ(map[i].getVector4fMap(), (*built)[i].getVector4fMap());
    EXPECT_EQ(map[i].intensity, (*built)[i].intensity);
  }
  size_t raw = 0;
  for (const auto& c : drive_->clouds) raw += c->size();
  EXPECT_GT(map.size(), 1000u);
  EXPECT_LT(map.size(), raw);  // voxelised

  const BuildingFileResult geo = readBuildingsGeoJson(dir + "/buildings_corrected.geojson");
  ASSERT_TRUE(geo.ok) << geo.error;
  EXPECT_EQ(geo.buildings.size(), drive_->truth.size());

  const OsmData osm = readOsmFile(dir + "/buildings_corrected.osm");
  ASSERT_TRUE(osm.ok) << osm.error;
  ASSERT_EQ(osm.buildings.size(), drive_->truth.size());
  const auto corrected = backend_->correctedBuildings();
  for (const auto& b : osm.buildings) {
    auto it = std::find_if(corrected.begin(), corrected.end(),
                           [&](const Building& c) { return c.id == b.id; });
    ASSERT_NE(it, corrected.end()) << "way id " << b.id << " kept";
    EXPECT_NEAR(b.outline_geo[0].lat, it->outline_geo[0].lat, 1e-7);  // OSM stores 1e-7 deg
  }

  const TrajectoryReadResult kitti = readKittiPoses(dir + "/trajectory_kitti.txt");
  ASSERT_TRUE(kitti.ok) << kitti.error;
  EXPECT_EQ(kitti.trajectory.size(), 12u);
  const TrajectoryReadResult tum = readTumTrajectory(dir + "/trajectory_tum.txt");
  ASSERT_TRUE(tum.ok) << tum.error;
  EXPECT_NEAR(tum.trajectory.back().stamp, 1.1, 1e-9);

  PoseGraph graph;
  const G2oReadResult g2o = readG2o(dir + "/graph.g2o", &graph);
  ASSERT_TRUE(g2o.ok) << g2o.message;
  EXPECT_GE(graph.numVertices(), 12u);
}

// save_map's map.pgm + map.yaml, read back as map_server reads them, are the grid of the keyframes
// at their optimised poses, cell by cell; the grid a caller keeps (the nodelet's) is the one saved.
TEST_F(ExportFixture, SaveMapWritesTheOccupancyGridAsMapServerReadsIt) {
  OccupancyGrid grid(backend_->params().grid);
  const GridMapUpdate update = updateGridMap(grid, backend_->keyframes());
  EXPECT_EQ(update.inserted, 12u);
  const OccupancyGridImage image = grid.image();
  const OccupancyGrid* kept = &grid;
  for (const OccupancyGrid* given : {static_cast<const OccupancyGrid*>(nullptr), kept}) {
    const std::string dir = tempDir(given ? "save_map_given_grid" : "save_map_grid");
    const MapExportResult r = saveMap(*backend_, dir, 0.2, nullptr, given);
    ASSERT_TRUE(r.success) << r.message;
    const test::MapServerMap map = test::readMapServerMap(dir + "/map.yaml");
    ASSERT_TRUE(map.error.empty()) << map.error;
    ASSERT_EQ(map.width, image.width);
    ASSERT_EQ(map.height, image.height);
    EXPECT_NEAR(map.origin_x, image.origin.x(), 1e-9);
    EXPECT_NEAR(map.origin_y, image.origin.y(), 1e-9);
    int mismatched = 0, occupied = 0;
    for (int y = 0; y < map.height; ++y)
      for (int x = 0; x < map.width; ++x) {
        const MapServerCell c = mapServerClass(image.at(x, y));
        const int8_t expected = c == MapServerCell::kOccupied ? 100
                                : c == MapServerCell::kFree   ? 0
                                                              : -1;
        mismatched += map.at(x, y) != expected;
        occupied += expected == 100;
      }
    EXPECT_EQ(mismatched, 0);
    EXPECT_GT(occupied, 100) << "the street's walls";
  }
}

// A bad grid parameter is one clear error and costs the save nothing else: every other file is
// written, the message says why map.pgm is missing.
TEST_F(ExportFixture, ABadGridResolutionSkipsOnlyTheGridWithTheReason) {
  GraphBackendParams params = backend_->params();
  params.grid.resolution = std::numeric_limits<double>::quiet_NaN();
  GraphBackend backend(params);
  backend.setOrigin(49.0, 8.4, 110.0);
  drive_->feed(backend, drive_->odometry(0.0, 1.0), drive_->truth);
  backend.update();
  const std::string dir = tempDir("save_map_bad_grid");
  const MapExportResult r = saveMap(backend, dir, 0.2);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.files.size(), 8u);
  EXPECT_FALSE(fs::exists(dir + "/map.pgm"));
  EXPECT_NE(r.message.find("no map.pgm: grid_resolution must be a finite number > 0"),
            std::string::npos)
      << r.message;
}

TEST_F(ExportFixture, AFailedOrInterruptedSaveLeavesThePreviousFilesUnchanged) {
  const std::string dir = tempDir("save_map_no_lost_work");
  ASSERT_TRUE(saveMap(*backend_, dir, 0.2).success);
  const auto before = folderContents(dir);
  // The coarse save's files, measured in a scratch folder: its map.pcd is small, another is larger.
  const std::string scratch = tempDir("save_map_coarse");
  ASSERT_TRUE(saveMap(*backend_, scratch, 5.0).success);
  const auto coarse = folderContents(scratch);
  const size_t map_bytes = coarse.at("map.pcd").size();
  size_t largest = 0;
  for (const auto& [name, content] : coarse) largest = std::max(largest, content.size());
  ASSERT_GT(largest, map_bytes) << "the test needs a file that fails after map.pcd was written";

  {
    const FileSizeLimit disk_full(map_bytes);  // map.pcd is written, a later file is not
    const MapExportResult r = saveMap(*backend_, dir, 5.0);
    EXPECT_FALSE(r.success);
    EXPECT_NE(r.message.find("File too large"), std::string::npos) << r.message;
    EXPECT_NE(r.message.find("previous files are unchanged"), std::string::npos) << r.message;
    EXPECT_TRUE(r.files.empty());
  }
  EXPECT_EQ(folderContents(dir), before) << "a failed save replaced some of the previous files";

  // A save killed mid-way (SIGINT) leaves its staging folder: the next save removes it.
  const pid_t child = fork();
  if (child == 0) _exit(0);
  waitpid(child, nullptr, 0);  // a pid that is gone
  const fs::path abandoned = fs::path(dir) / (".partial-" + std::to_string(child) + "-0");
  fs::create_directories(abandoned);
  std::ofstream(abandoned / "map.pcd") << "half";
  EXPECT_EQ(folderContents(dir).size(), before.size() + 1);

  const MapExportResult r = saveMap(*backend_, dir, 5.0);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_FALSE(fs::exists(abandoned));
  const auto after = folderContents(dir);
  EXPECT_EQ(after.size(), before.size());
  EXPECT_EQ(after.at("map.pcd"), coarse.at("map.pcd"));
  EXPECT_EQ(after.at("trajectory_tum.txt"), before.at("trajectory_tum.txt"));
}

TEST_F(ExportFixture, DumpGraphKeepsEveryInput) {
  const std::string dir = tempDir("dump_graph");
  const MapExportResult r = dumpGraph(*backend_, dir);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(std::distance(fs::directory_iterator(dir + "/keyframes"), fs::directory_iterator{}),
            12);
  std::ifstream kf(dir + "/keyframes.csv"), loops(dir + "/loops.csv");
  std::string line;
  int rows = 0;
  while (std::getline(kf, line)) rows += line[0] != '#';
  EXPECT_EQ(rows, 12);
  rows = 0;
  while (std::getline(loops, line)) rows += line[0] != '#';
  EXPECT_EQ(rows, 1);
  std::ifstream floors(dir + "/floors.csv");
  rows = 0;
  while (std::getline(floors, line)) rows += line[0] != '#';
  EXPECT_EQ(rows, 6);
  EXPECT_TRUE(fs::exists(dir + "/origin.txt"));
  EXPECT_TRUE(readBuildingsGeoJson(dir + "/buildings_prior.geojson").ok);
}

TEST_F(ExportFixture, ReplayingADumpReproducesTheBackend) {
  const std::string dir = tempDir("dump_replay");
  ASSERT_TRUE(dumpGraph(*backend_, dir).success);
  GraphDump dump;
  std::string error;
  ASSERT_TRUE(readGraphDump(dir, dump, &error)) << error;
  EXPECT_EQ(dump.keyframes.size(), 12u);
  EXPECT_EQ(dump.loops.size(), 1u);
  for (const auto& kf : dump.keyframes) {
    ASSERT_EQ(kf.floor.has_value(), kf.id % 2 == 0) << kf.id;
    if (kf.floor)
      EXPECT_NEAR(kf.floor->w(), 1.73 / Eigen::Vector4d(0.01, -0.005, 1.0, 1.73).norm(), 1e-12);
  }
  EXPECT_EQ(dump.buildings.size(), backend_->buildings().size());
  ASSERT_TRUE(dump.origin && dump.initial_heading);
  // The heading the run started from, bit for bit: not the first keyframe's optimised one,
  // which would hand a replay the outcome of the run it replays.
  EXPECT_EQ(*dump.initial_heading, backend_->params().initial_yaw);
  GraphBackendParams params = backend_->params();
  params.initial_yaw = *dump.initial_heading;
  GraphBackend replay(params);
  replayGraphDump(dump, replay, 1000);  // one update, as the fixture did
  // Buildings come back through GeoJSON lat/lon (1e-7 deg, ~1 cm): mm-level differences.
  const Trajectory a = backend_->trajectory(), b = replay.trajectory();
  ASSERT_EQ(a.size(), b.size());
  size_t tied = 0;
  for (const auto& kf : replay.keyframes()) tied += kf.floor_tied;
  EXPECT_EQ(tied, 6u);  // the floors came back and were tied to each other
  for (size_t k = 0; k < a.size(); ++k)
    EXPECT_LT((a[k].pose.translation() - b[k].pose.translation()).norm(), 0.01) << k;
  const auto ba = backend_->buildings(), bb = replay.buildings();
  ASSERT_EQ(ba.size(), bb.size());
  for (size_t i = 0; i < ba.size(); ++i) {
    EXPECT_EQ(ba[i].observations, bb[i].observations);
    EXPECT_LT((ba[i].pose.translation() - bb[i].pose.translation()).norm(), 0.02);
  }
  // A malformed row is reported with its file and line.
  std::ofstream(dir + "/loops.csv") << "# header\n11 2 not-a-number\n";
  EXPECT_FALSE(readGraphDump(dir, dump, &error));
  EXPECT_NE(error.find("loops.csv:2"), std::string::npos) << error;
  std::ofstream(dir + "/loops.csv") << "# header\n";
  std::ofstream(dir + "/floors.csv") << "# header\n0 0 0 1 nan\n";
  EXPECT_FALSE(readGraphDump(dir, dump, &error));
  EXPECT_NE(error.find("floors.csv:2"), std::string::npos) << error;
}

TEST(MapExport, DumpKeepsTheGnssAndInsAidingForReplays) {
  GraphBackendParams params;
  params.initial_yaw_known = true;
  GraphBackend backend(params);
  backend.setOrigin(49.0, 8.4, 110.0);
  for (uint64_t k = 0; k < 3; ++k) {
    KeyframeInput in;
    in.id = k;
    in.stamp = 100.0 + k;
    in.accum_distance = 2.0 * k;
    in.odom_pose.translation() = Eigen::Vector3d(2.0 * k, 0.0, 0.0);
    if (k != 1) {  // keyframe 1 had no fix and no INS sample
      in.gnss_position = Eigen::Vector2d(2.0 * k + 0.3, -0.4);
      in.gnss_std = 1.8;
      in.gnss_altitude = 0.5 * k;
      in.ins_yaw = 0.01 * (k + 1);
    }
    backend.addKeyframe(in);
  }
  backend.update();  // keyframes enter the graph at the update
  const std::string dir = ::testing::TempDir() + "/dump_aiding";
  fs::remove_all(dir);
  const MapExportResult dumped = dumpGraph(backend, dir, false);
  ASSERT_TRUE(dumped.success) << dumped.message;
  EXPECT_FALSE(fs::exists(dir + "/keyframes"));  // without clouds
  GraphDump dump;
  std::string error;
  ASSERT_TRUE(readGraphDump(dir, dump, &error)) << error;
  ASSERT_EQ(dump.keyframes.size(), 3u);
  for (const auto& kf : dump.keyframes) {
    ASSERT_EQ(kf.gnss_position.has_value(), kf.id != 1) << kf.id;
    EXPECT_EQ(kf.gnss_std.has_value(), kf.id != 1);
    EXPECT_EQ(kf.gnss_altitude.has_value(), kf.id != 1);
    ASSERT_EQ(kf.ins_yaw.has_value(), kf.id != 1);
    if (kf.id == 1) continue;
    EXPECT_NEAR(kf.gnss_position->x(), 2.0 * kf.id + 0.3, 1e-12);
    EXPECT_NEAR(kf.gnss_position->y(), -0.4, 1e-12);
    EXPECT_NEAR(*kf.gnss_std, 1.8, 1e-12);
    EXPECT_NEAR(*kf.gnss_altitude, 0.5 * kf.id, 1e-12);
    EXPECT_NEAR(*kf.ins_yaw, 0.01 * (kf.id + 1), 1e-12);
  }
}

TEST(MapExport, EmptyGraphAndUnwritableFolderFailWithReason) {
  GraphBackend empty;
  MapExportResult r = saveMap(empty, ::testing::TempDir() + "/never", 0.1);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("empty"), std::string::npos);
  EXPECT_FALSE(dumpGraph(empty, ::testing::TempDir() + "/never").success);

  GraphBackend one;
  KeyframeInput kf;
  one.addKeyframe(kf);
  one.update();
  const std::string file = ::testing::TempDir() + "/a_file";
  std::ofstream(file) << "x";
  r = saveMap(one, file + "/sub", 0.1);  // a folder below a regular file cannot exist
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("cannot create"), std::string::npos) << r.message;
}
