// The occupancy grid (cloud/occupancy_grid.h) on a synthetic walled yard, and the map_server pair
// (io/map_server_files.h) read back with a reader that follows map_server's documented format.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "map_server_reader.h"
#include "osm_graph_slam/cloud/occupancy_grid.h"
#include "osm_graph_slam/io/map_server_files.h"

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

constexpr double kSensorHeight = 1.73;  ///< base_link above the ground, as on KITTI

/// A yard: walls 3 m high at x = ±6 and y = ±4, flat ground; only what a sensor at `sensor`
/// (map frame, on the ground plane) sees, given in its base_link frame (yaw 0).
PointCloud yardCloud(const Eigen::Vector2d& sensor) {
  PointCloud cloud;
  auto add = [&](double x, double y, double z) {
    PointT p;
    p.x = static_cast<float>(x - sensor.x());
    p.y = static_cast<float>(y - sensor.y());
    p.z = static_cast<float>(z - kSensorHeight);
    p.intensity = 0.0f;
    cloud.push_back(p);
  };
  for (double x = -5.95; x < 6.0; x += 0.1)
    for (double y = -3.95; y < 4.0; y += 0.1) add(x, y, 0.0);
  for (double h = 0.05; h < 3.0; h += 0.1) {
    for (double y = -3.95; y < 4.0; y += 0.1) add(6.0, y, h), add(-6.0, y, h);
    for (double x = -5.95; x < 6.0; x += 0.1) add(x, 4.0, h), add(x, -4.0, h);
  }
  return cloud;
}

Eigen::Isometry3d at(const Eigen::Vector2d& xy) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() << xy.x(), xy.y(), 0.0;
  return pose;
}

const std::vector<Eigen::Vector2d> kSensors = {
    {-2.0, 0.0}, {-1.0, 0.5}, {0.0, 0.0}, {1.0, -0.5}, {2.0, 0.0}};

OccupancyGrid yardGrid(const OccupancyGridParams& params = {}) {
  OccupancyGrid grid(params);
  for (size_t i = 0; i < kSensors.size(); ++i)
    grid.insertKeyframe(i, at(kSensors[i]), yardCloud(kSensors[i]));
  return grid;
}

/// The cell value at a map position (-2 outside the image).
int valueAt(const OccupancyGridImage& image, double x, double y) {
  const int cx = static_cast<int>(std::floor((x - image.origin.x()) / image.resolution));
  const int cy = static_cast<int>(std::floor((y - image.origin.y()) / image.resolution));
  if (cx < 0 || cy < 0 || cx >= image.width || cy >= image.height) return -2;
  return image.at(cx, cy);
}

/// Cells of `a` whose value `b` does not have at the same place (unknown outside `b`).
int differingCells(const OccupancyGridImage& a, const OccupancyGridImage& b) {
  int differing = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const Eigen::Vector2d p =
          a.origin + (Eigen::Vector2d(x, y) + Eigen::Vector2d(0.5, 0.5)) * a.resolution;
      const int in_b = valueAt(b, p.x(), p.y());
      differing += (in_b == -2 ? -1 : in_b) != a.at(x, y);
    }
  return differing;
}

}  // namespace

TEST(OccupancyGrid, WallsAreOccupiedTheYardFreeAndBehindTheWallsUnknown) {
  const OccupancyGridImage image = yardGrid().image();
  ASSERT_GT(image.width, 0);
  EXPECT_DOUBLE_EQ(image.resolution, 0.2);
  int wall_cells = 0, wall_occupied = 0, inside_cells = 0, inside_free = 0, behind_known = 0;
  for (double t = -3.5; t <= 3.5; t += 0.2) {  // along the long walls' inner parts
    for (double x : {-5.9, 6.1}) {
      ++wall_cells;
      wall_occupied += mapServerClass(valueAt(image, x, t)) == MapServerCell::kOccupied;
      behind_known += valueAt(image, x + (x > 0 ? 1.0 : -1.0), t) >= 0;
    }
  }
  for (double x = -5.3; x <= 5.3; x += 0.2)
    for (double y = -3.3; y <= 3.3; y += 0.2) {
      ++inside_cells;
      inside_free += mapServerClass(valueAt(image, x, y)) == MapServerCell::kFree;
    }
  EXPECT_EQ(wall_occupied, wall_cells);
  EXPECT_GE(inside_free, 0.95 * inside_cells) << inside_free << " of " << inside_cells;
  EXPECT_EQ(behind_known, 0);
  EXPECT_GE(valueAt(image, 6.1, 0.0), 90);  // five keyframes' hits, clamped at 97 %
  EXPECT_LE(valueAt(image, 3.0, 0.0), 19);
  EXPECT_LT(valueAt(image, 8.0, 0.0), 0);  // unknown, or beyond the image
}

TEST(OccupancyGrid, AMovedKeyframeIsRenderedAtItsNewPlaceOnly) {
  OccupancyGrid grid = yardGrid();
  // A loop moves the whole yard 1 m east and turns it 10 degrees.
  std::map<uint64_t, Eigen::Isometry3d> moved;
  const Eigen::Isometry3d correction(
      Eigen::Translation3d(1.0, 0.0, 0.0) *
      Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
  for (size_t i = 0; i < kSensors.size(); ++i) moved[i] = correction * at(kSensors[i]);
  EXPECT_EQ(grid.updatePoses(moved), kSensors.size());
  // Exactly what a grid built at the new poses holds: no trace of the old ones is left.
  OccupancyGrid fresh;
  for (size_t i = 0; i < kSensors.size(); ++i)
    fresh.insertKeyframe(i, moved[i], yardCloud(kSensors[i]));
  const OccupancyGridImage a = grid.image(), b = fresh.image();
  const Eigen::Vector2d new_wall = (correction * Eigen::Vector3d(6.0, 0.0, 0.0)).head<2>();
  EXPECT_EQ(mapServerClass(valueAt(a, new_wall.x(), new_wall.y())), MapServerCell::kOccupied);
  EXPECT_EQ(mapServerClass(valueAt(a, 6.1, 0.0)), MapServerCell::kFree);  // the old wall's place
  EXPECT_EQ(differingCells(a, b), 0);
  EXPECT_EQ(differingCells(b, a), 0);
  // Small moves leave cells alone; a full re-render gives the same grid as the incremental one.
  std::map<uint64_t, Eigen::Isometry3d> nudged = moved;
  nudged[0].translation().x() += 0.01;
  EXPECT_EQ(grid.updatePoses(nudged), 0u);
  grid.rerender();
  EXPECT_EQ(grid.image().cells, b.cells);
}

TEST(OccupancyGrid, TheFloorPlaneDecidesTheGroundOnASlope) {
  // A 10 % slope up to the east, no walls: without the plane the far ground is an obstacle band.
  PointCloud cloud;
  for (double x = -20.0; x <= 20.0; x += 0.2)
    for (double y = -3.0; y <= 3.0; y += 0.2) {
      PointT p;
      p.x = x, p.y = y, p.z = 0.1 * x - kSensorHeight;
      cloud.push_back(p);
    }
  const Eigen::Vector4d slope = Eigen::Vector4d(-0.1, 0.0, 1.0, kSensorHeight).normalized();
  OccupancyGridParams params;
  params.ground_tolerance = 0.0;  // the plane alone
  OccupancyGrid with_plane(params), flat(params);
  with_plane.insertKeyframe(0, Eigen::Isometry3d::Identity(), cloud, slope);
  flat.insertKeyframe(0, Eigen::Isometry3d::Identity(), cloud);
  auto occupied = [](const OccupancyGridImage& image) {
    int n = 0;
    for (int8_t v : image.cells) n += mapServerClass(v) == MapServerCell::kOccupied;
    return n;
  };
  EXPECT_EQ(occupied(with_plane.image()), 0);
  EXPECT_GT(occupied(flat.image()), 100);
}

TEST(OccupancyGrid, BadParametersAreOneClearError) {
  auto errorOf = [](OccupancyGridParams p) -> std::string {
    try {
      OccupancyGrid grid(p);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return {};
  };
  for (double resolution : {0.0, -0.1, std::numeric_limits<double>::quiet_NaN(),
                            std::numeric_limits<double>::infinity()}) {
    OccupancyGridParams p;
    p.resolution = resolution;
    EXPECT_NE(errorOf(p).find("grid_resolution"), std::string::npos) << resolution;
  }
  OccupancyGridParams inverted;
  inverted.min_height = 2.0, inverted.max_height = 0.5;
  EXPECT_NE(errorOf(inverted).find("grid_min_height"), std::string::npos);
  OccupancyGridParams certain;
  certain.hit_probability = 1.0;
  EXPECT_NE(errorOf(certain).find("grid_hit_probability"), std::string::npos);
  OccupancyGridParams fine_sectors;  // would allocate 36 million sectors per keyframe
  fine_sectors.azimuth_step_deg = 1e-5;
  EXPECT_NE(errorOf(fine_sectors).find("grid_azimuth_step_deg"), std::string::npos);
  OccupancyGridParams fine_ground;
  fine_ground.ground_cell = 1e-4;
  EXPECT_NE(errorOf(fine_ground).find("grid_ground_cell"), std::string::npos);
  EXPECT_EQ(errorOf(OccupancyGridParams()), "");
}

TEST(MapServerFiles, ThePairReadsBackAsTheGridCellByCell) {
  const OccupancyGridImage image = yardGrid().image();
  const fs::path dir = fs::path(::testing::TempDir()) / "map_server_pair";
  fs::create_directories(dir);
  std::ofstream(dir / "map.pgm", std::ios::binary) << mapServerPgm(image);
  std::ofstream(dir / "map.yaml") << mapServerYaml(image, "map.pgm");

  const test::MapServerMap map = test::readMapServerMap((dir / "map.yaml").string());
  ASSERT_TRUE(map.error.empty()) << map.error;
  ASSERT_EQ(map.width, image.width);
  ASSERT_EQ(map.height, image.height);
  EXPECT_DOUBLE_EQ(map.resolution, image.resolution);
  EXPECT_DOUBLE_EQ(map.origin_x, image.origin.x());
  EXPECT_DOUBLE_EQ(map.origin_y, image.origin.y());
  EXPECT_DOUBLE_EQ(map.origin_yaw, 0.0);
  int occupied = 0, free = 0, mismatched = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const MapServerCell expected = mapServerClass(image.at(x, y));
      const int8_t read = map.at(x, y);
      const MapServerCell got = read == 100 ? MapServerCell::kOccupied
                                : read == 0 ? MapServerCell::kFree
                                            : MapServerCell::kUnknown;
      mismatched += got != expected;
      occupied += got == MapServerCell::kOccupied;
      free += got == MapServerCell::kFree;
    }
  EXPECT_EQ(mismatched, 0);
  EXPECT_GT(occupied, 150);  // the yard's 40 m of wall at 0.2 m
  EXPECT_GT(free, 1000);
}
