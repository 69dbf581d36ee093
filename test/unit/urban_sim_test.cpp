// The urban simulator: determinism, scan statistics, geometry against the true outlines, route,
// prior map, the Karlsruhe extract, front-end registration on simulated scans, and the stereo
// camera (its pairs' geometry and the stereo odometry on them).
#include <gtest/gtest.h>
#include <pcl/filters/voxel_grid.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>

#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/registration/registration.h"
#include "osm_graph_slam/sim/sim_random.h"
#include "osm_graph_slam/sim/simulator.h"
#include "osm_graph_slam/sim/stereo_camera_sim.h"
#include "osm_graph_slam/visual/stereo_odometry.h"
#include "sim_worlds.h"
#include "test_data.h"

namespace osm_graph_slam {
// Weak: the front-end (registration back-ends) may not be linked into this branch yet.
std::unique_ptr<Registration> createRegistration(const RegistrationParams& params)
    __attribute__((weak));
}  // namespace osm_graph_slam

namespace fs = std::filesystem;
using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

SimulationParams smallCity(uint64_t seed) {
  SimulationParams p;
  p.seed = seed;
  p.city.blocks_x = 5;
  p.city.blocks_y = 4;
  p.route.length = 900.0;
  return p;
}

double distanceToOutline(const Eigen::Vector2d& p, const Polygon2& poly) {
  double best = 1e18;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d a = poly[i], e = poly[(i + 1) % poly.size()] - a;
    const double t = std::clamp((p - a).dot(e) / e.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (a + t * e - p).norm());
  }
  return best;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::string fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(UrbanSim, SameSeedSameBytesDifferentSeedDifferentWorld) {
  const fs::path a = fs::path(::testing::TempDir()) / "ogs_sim_det_a";
  const fs::path b = fs::path(::testing::TempDir()) / "ogs_sim_det_b";
  for (const auto& dir : {a, b}) {
    fs::remove_all(dir);
    SimulationParams p = smallCity(7);
    p.max_scans = 3;
    p.motion_distortion = true;
    UrbanSimulator sim;
    std::string error;
    ASSERT_TRUE(sim.build(p, &error)) << error;
    SimulationStats stats;
    ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
    EXPECT_EQ(stats.scans, 3u);
  }
  size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(a)) {
    if (!entry.is_regular_file()) continue;
    const fs::path rel = fs::relative(entry.path(), a);
    ASSERT_TRUE(fs::exists(b / rel)) << rel;
    EXPECT_EQ(fileBytes(entry.path()), fileBytes(b / rel)) << rel << " differs between runs";
    ++files;
  }
  // 3 scans, 3 OXTS, 3 exact OXTS (oxts_true), 5 timestamps, 2 calib, 3 truth poses, 4 map/info
  EXPECT_EQ(files, 23u);

  UrbanSimulator other;
  ASSERT_TRUE(other.build(smallCity(8)));
  UrbanSimulator same;
  ASSERT_TRUE(same.build(smallCity(7)));
  EXPECT_NE(other.scene().world.buildings.front().outline.front(),
            same.scene().world.buildings.front().outline.front());
}

// A second drive through the same world: the world seed fixes the city (every building, its
// height), the seed the route, its clutter and noise.
TEST(UrbanSim, WorldSeedKeepsTheCityAndTheSeedChangesTheRoute) {
  SimulationParams map_drive = smallCity(7), other_drive = smallCity(8);
  other_drive.world_seed = 7;
  UrbanSimulator a, b;
  ASSERT_TRUE(a.build(map_drive));
  ASSERT_TRUE(b.build(other_drive));
  const auto& wa = a.scene().world.buildings;
  const auto& wb = b.scene().world.buildings;
  ASSERT_EQ(wa.size(), wb.size());
  for (size_t i = 0; i < wa.size(); ++i) {
    EXPECT_EQ(wa[i].outline, wb[i].outline) << "building " << i;
    EXPECT_EQ(wa[i].height, wb[i].height) << "building " << i;
  }
  const auto& ra = a.route().waypoints;
  const auto& rb = b.route().waypoints;
  EXPECT_TRUE(ra.size() != rb.size() || !std::equal(ra.begin(), ra.end(), rb.begin()))
      << "another seed drives another route";
}

TEST(UrbanSim, ProceduralCityHasVariedShapesAndARouteWithRevisit) {
  const UrbanSimulator& sim = test::defaultSimulator();
  std::map<std::string, int> shapes;
  for (const auto& tags : sim.scene().building_tags) ++shapes[tags.at("sim:shape")];
  EXPECT_GT(shapes["rectangle"], 50);
  EXPECT_GT(shapes["l_shape"], 20);
  EXPECT_GE(shapes["round"], 3);
  for (const auto& b : sim.scene().world.buildings) {
    EXPECT_GE(b.height, 8.0);
    EXPECT_LE(b.height, 25.0);
  }
  const Trajectory& traj = sim.trajectory();
  EXPECT_GT(traj.length(), 1300.0);
  EXPECT_LT(traj.length(), 2000.0);
  EXPECT_GE(countRevisits(traj), 1);
  // Ends where it started: a loop closure opportunity.
  EXPECT_LT((traj.samples().back().position - traj.samples().front().position).norm(), 1.0);
  const double mean_speed = traj.length() / traj.duration();
  EXPECT_GT(mean_speed, 6.0);
  EXPECT_LT(mean_speed, 8.01);
  EXPECT_LT(traj.maxYawRate() * 180 / M_PI, 40.0);  // realistic for a car in town
  EXPECT_LE(traj.maxLateralAccel(), 2.5 + 1e-6);
  EXPECT_GT(sim.scene().world.primitives.size(), 500u);
  EXPECT_GE(sim.scene().world.moving.size(), 4u);
  for (const auto& p : sim.scene().world.primitives) {
    if (p.label == SimLabel::kFence)
      EXPECT_LE(p.z1 - sim.scene().world.ground.height(p.center.x(), p.center.y()), 1.5 + 1e-9);
  }
  // Gentle ground.
  EXPECT_LT(sim.scene().world.ground.maxSlope(), 0.06);
}

TEST(UrbanSim, ScanStatisticsArePlausibleForAnHdl64e) {
  const UrbanSimulator& sim = test::defaultSimulator();
  for (size_t k : {0u, 300u, 900u}) {
    const SimulatedScan scan = sim.simulate(k);
    EXPECT_GT(scan.cloud.size(), 105000u) << "scan " << k;
    EXPECT_LT(scan.cloud.size(), 133000u) << "scan " << k;
    size_t building = 0, ground = 0;
    double max_range = 0.0;
    for (size_t i = 0; i < scan.cloud.size(); ++i) {
      building += scan.labels[i] == SimLabel::kBuilding;
      ground += scan.labels[i] == SimLabel::kGround;
      const auto& p = scan.cloud[i];
      max_range = std::max(max_range, double(p.getVector3fMap().norm()));
      ASSERT_GE(p.intensity, 0.0f);
      ASSERT_LE(p.intensity, 1.0f);
    }
    const double fb = double(building) / scan.cloud.size();
    const double fg = double(ground) / scan.cloud.size();
    EXPECT_GT(fb, 0.08) << "scan " << k;
    EXPECT_LT(fb, 0.6) << "scan " << k;
    EXPECT_GT(fg, 0.3) << "scan " << k;
    EXPECT_LT(fg, 0.85) << "scan " << k;
    EXPECT_LE(max_range, 120.0 + 0.2);
  }
}

// Intensity by surface class and place: painted markings and asphalt patches on the ground, glass
// in the facades, leaf clumps; the points themselves are those of a uniform reflectivity.
TEST(UrbanSim, IntensityCarriesTextureAndLeavesTheGeometryAlone) {
  const UrbanSimulator& sim = test::defaultSimulator();
  LidarModel textured = LidarModel::hdl64e(), plain = textured;
  plain.texture.enabled = false;
  const double t = sim.scanTime(300);
  const SensorPoseFn pose = [&sim](double s) { return sim.sensorPose(s); };
  const SimulatedScan a = simulateScan(sim.scene().world, textured, pose, t, 7, 300);
  const SimulatedScan b = simulateScan(sim.scene().world, plain, pose, t, 7, 300);
  ASSERT_EQ(a.cloud.size(), b.cloud.size());
  // Both scans draw the same noise: the ratio of the intensities is the texture's reflectance
  // over the surface's own, times a shading both share.
  std::map<SimLabel, std::vector<double>> ratio;
  for (size_t i = 0; i < a.cloud.size(); ++i) {
    ASSERT_EQ(a.cloud[i].getVector3fMap(), b.cloud[i].getVector3fMap()) << i;
    if (b.cloud[i].intensity > 0.05f)
      ratio[a.labels[i]].push_back(a.cloud[i].intensity / b.cloud[i].intensity);
  }
  const auto share = [](const std::vector<double>& v, auto&& pred) {
    return double(std::count_if(v.begin(), v.end(), pred)) / double(std::max<size_t>(1, v.size()));
  };
  const std::vector<double>& ground = ratio[SimLabel::kGround];
  ASSERT_GT(ground.size(), 10000u);
  // Markings (reflectance 0.7 on asphalt of 0.18): a few percent of the ground returns.
  const double markings = share(ground, [](double r) { return r > 2.5; });
  EXPECT_GT(markings, 0.01);
  EXPECT_LT(markings, 0.06);
  // Asphalt patches +-35 %: the shades spread the ratio.
  EXPECT_GT(share(ground, [](double r) { return r < 0.85; }), 0.15);
  EXPECT_GT(share(ground, [](double r) { return r > 1.15 && r < 2.0; }), 0.15);
  // Glass (0.05 against walls of 0.2-0.5): a large share of the facade returns.
  const double glass = share(ratio[SimLabel::kBuilding], [](double r) { return r < 0.5; });
  std::cout << "[urban_sim] intensity texture: markings " << markings
            << " of ground returns, glass " << glass << " of facade returns\n";
  EXPECT_GT(glass, 0.15);
  EXPECT_LT(glass, 0.6);
}

TEST(UrbanSim, TrueOutlinesLieOnTheWallPoints) {
  const UrbanSimulator& sim = test::defaultSimulator();
  int checked = 0;
  for (size_t k : {10u, 400u, 1200u}) {
    const SimulatedScan scan = sim.simulate(k);
    const Eigen::Isometry3d T = sim.sensorPose(sim.scanTime(k));
    std::map<int, std::vector<double>> per_building;
    for (size_t i = 0; i < scan.cloud.size(); ++i) {
      if (scan.labels[i] != SimLabel::kBuilding) continue;
      const Eigen::Vector3d w = T * scan.cloud[i].getVector3fMap().cast<double>();
      per_building[scan.objects[i]].push_back(
          distanceToOutline(w.head<2>(), sim.scene().world.buildings[scan.objects[i]].outline));
    }
    for (const auto& [b, d] : per_building) {
      if (d.size() < 50) continue;
      EXPECT_LT(median(d), 0.05) << "building " << sim.scene().world.buildings[b].osm_id;
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
}

TEST(UrbanSim, GridRayCasterEqualsTestingEveryObject) {
  const UrbanSimulator& sim = test::defaultSimulator();
  World brute = sim.scene().world;
  brute.use_grid = false;
  SimRng rng(99);
  int hits = 0;
  for (int i = 0; i < 4000; ++i) {
    const Eigen::Isometry3d T = sim.sensorPose(rng.uniform(0.0, sim.trajectory().duration()));
    const double az = rng.uniform(-M_PI, M_PI), el = rng.uniform(-0.43, 0.05);
    const Eigen::Vector3d d =
        T.linear() *
        Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    RayHit a, b;
    const bool ha = sim.scene().world.castRay(T.translation(), d, 120.0, 0.0, a);
    const bool hb = brute.castRay(T.translation(), d, 120.0, 0.0, b);
    ASSERT_EQ(ha, hb) << "ray " << i;
    if (!ha) continue;
    ++hits;
    EXPECT_NEAR(a.range, b.range, 1e-9) << "ray " << i;
    EXPECT_EQ(a.label, b.label) << "ray " << i;
    EXPECT_EQ(a.object, b.object) << "ray " << i;
  }
  EXPECT_GT(hits, 3000);
}

TEST(UrbanSim, MotionDistortionMovesPointsByTheSweepMotion) {
  SimulationParams p = smallCity(3);
  UrbanSimulator still, distorted;
  ASSERT_TRUE(still.build(p));
  p.motion_distortion = true;
  ASSERT_TRUE(distorted.build(p));
  const auto a = still.simulate(20), b = distorted.simulate(20);
  // The vehicle moves ~0.8 m per sweep: distorted scans differ, but not wildly.
  double mean_a = 0, mean_b = 0;
  for (const auto& pt : a.cloud) mean_a += pt.x;
  for (const auto& pt : b.cloud) mean_b += pt.x;
  EXPECT_GT(std::abs(mean_a / a.cloud.size() - mean_b / b.cloud.size()), 1e-3);
  EXPECT_NEAR(double(a.cloud.size()), double(b.cloud.size()), 0.02 * a.cloud.size());
}

TEST(UrbanSim, PriorMapPerturbsRemovesAndAddsBuildings) {
  const fs::path dir = fs::path(::testing::TempDir()) / "ogs_sim_prior";
  fs::remove_all(dir);
  SimulationParams p;
  p.max_scans = 2;
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  SimulationStats stats;
  std::string error;
  ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
  const size_t n = sim.scene().world.buildings.size();
  EXPECT_EQ(stats.prior_removed, size_t(std::llround(0.05 * n)));
  EXPECT_EQ(stats.prior_phantom, size_t(std::llround(0.03 * n)));
  EXPECT_EQ(stats.prior_perturbed + stats.prior_removed, n);

  // Offsets: sigma 1 m and 2 deg.
  std::ifstream csv(dir / "prior_offsets.csv");
  std::string line;
  std::vector<double> dx, dth;
  std::map<int64_t, std::array<double, 5>> offsets;
  while (std::getline(csv, line)) {
    if (line.rfind("#", 0) == 0 || line.rfind("osm_id", 0) == 0) continue;
    long long id;
    char status[16];
    double x, y, th, cx, cy;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lld,%15[a-z],%lf,%lf,%lf,%lf,%lf", &id, status, &x, &y,
                          &th, &cx, &cy),
              7)
        << line;
    if (std::string(status) == "perturbed") {
      dx.push_back(x);
      dth.push_back(th);
      offsets[id] = {x, y, th, cx, cy};
    }
  }
  auto rms = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x * x;
    return std::sqrt(s / v.size());
  };
  EXPECT_NEAR(rms(dx), 1.0, 0.2);
  EXPECT_NEAR(rms(dth), 2.0, 0.4);

  // prior.osm reads back with the OSM reader; each perturbed building is the true one moved by
  // its recorded offset.
  const OsmData prior = readOsmFile((dir / "prior.osm").string());
  ASSERT_TRUE(prior.ok) << prior.error;
  EXPECT_EQ(prior.buildings.size(), stats.prior_perturbed + stats.prior_phantom);
  std::map<int64_t, const SimBuilding*> truth;
  for (const auto& b : sim.scene().world.buildings) truth[b.osm_id] = &b;
  int compared = 0;
  for (Building b : prior.buildings) {
    if (!offsets.count(b.id)) continue;
    sim.enu().project(b);
    const auto& o = offsets[b.id];
    const Eigen::Matrix2d R = Pose2(0, 0, o[2] * M_PI / 180).rotation();
    const Polygon2& t = truth.at(b.id)->outline;
    ASSERT_EQ(b.outline_enu.size(), t.size());
    for (size_t i = 0; i < t.size(); ++i) {
      const Eigen::Vector2d expected = R * (t[i] - Eigen::Vector2d(o[3], o[4])) +
                                       Eigen::Vector2d(o[3], o[4]) + Eigen::Vector2d(o[0], o[1]);
      EXPECT_LT((b.outline_enu[i] - expected).norm(), 0.01);
    }
    ++compared;
  }
  EXPECT_EQ(size_t(compared), stats.prior_perturbed);
  EXPECT_TRUE(fs::exists(dir / "buildings_true.geojson"));
}

TEST(UrbanSim, OutputIsAKittiRawDriveThatKitti2BagConverts) {
  const fs::path dir = fs::path(::testing::TempDir()) / "ogs_sim_kitti";
  fs::remove_all(dir);
  SimulationParams p = smallCity(5);
  p.max_scans = 3;
  p.nav.rtk = true;  // exact GNSS/INS: the first OXTS fix is the true pose
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  SimulationStats stats;
  ASSERT_TRUE(sim.writeDataset(dir.string(), stats));
  KittiRawDrive drive;
  std::string error;
  ASSERT_TRUE(openKittiRawDrive(stats.drive_dir, "", drive, &error)) << error;
  EXPECT_EQ(drive.scan_files.size(), 3u);
  EXPECT_EQ(drive.scan_stamps[1] - drive.scan_stamps[0], 100000000);
  EXPECT_NEAR(drive.T_velo_imu.inverse().translation().z(), 0.80, 1e-12);
  // OXTS of scan 0 is the true first fix: back to ENU it is the true IMU position.
  OxtsRecord x;
  ASSERT_TRUE(readOxtsFile(drive.oxts_files[0], x, &error)) << error;
  const Eigen::Vector3d enu = sim.enu().toEnu(x.lat, x.lon, x.alt);
  EXPECT_LT((enu - sim.basePose(0).translation()).norm(), 1e-3);
  std::vector<Eigen::Isometry3d> gt;
  ASSERT_TRUE(readKittiPoses((dir / "ground_truth" / "poses_velo.txt").string(), gt));
  ASSERT_EQ(gt.size(), 3u);
  EXPECT_NEAR(gt[0].translation().z() -
                  sim.scene().world.ground.height(gt[0].translation().x(), gt[0].translation().y()),
              1.73, 0.05);
  KittiRawBagOptions o;
  o.drive_dir = stats.drive_dir;
  o.bag_path = (dir / "sim.bag").string();
  const auto r = convertKittiRawToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.clouds, 3u);
}

TEST(UrbanSim, KarlsruheExtractBuildsAllBuildingsAndARouteOnItsRoads) {
  const std::string path = test::sharedDataPath("osm/2011_09_26_drive_0005_sync.osm");
  OGS_REQUIRE_SHARED_FILE(path);
  const OsmData osm = readOsmFile(path);
  ASSERT_TRUE(osm.ok) << osm.error;
  SimulationParams p;
  p.osm_path = path;
  UrbanSimulator sim;
  std::string error;
  ASSERT_TRUE(sim.build(p, &error)) << error;
  EXPECT_EQ(sim.scene().world.buildings.size(), osm.buildings.size());
  EXPECT_GE(osm.buildings.size(), 170u);
  std::set<int64_t> ids;
  for (const auto& b : sim.scene().world.buildings) ids.insert(b.osm_id);
  for (const auto& b : osm.buildings) EXPECT_TRUE(ids.count(b.id)) << b.id;
  // Every route waypoint is a node of a drivable highway way; the smoothed path stays on them.
  std::vector<Eigen::Vector2d> road_nodes;
  for (const auto& r : sim.scene().roads) road_nodes.insert(road_nodes.end(), r.begin(), r.end());
  for (const auto& w : sim.route().waypoints) {
    double best = 1e18;
    for (const auto& n : road_nodes) best = std::min(best, (n - w).norm());
    EXPECT_LT(best, 1e-6);
  }
  for (size_t i = 0; i < sim.trajectory().samples().size(); i += 50) {
    const Eigen::Vector2d q = sim.trajectory().samples()[i].position;
    double best = 1e18;
    for (const auto& r : sim.scene().roads) {
      for (size_t k = 0; k + 1 < r.size(); ++k) {
        const Eigen::Vector2d e = r[k + 1] - r[k];
        const double t = std::clamp((q - r[k]).dot(e) / std::max(e.squaredNorm(), 1e-12), 0.0, 1.0);
        best = std::min(best, (r[k] + t * e - q).norm());
      }
    }
    EXPECT_LT(best, 4.0) << "trajectory sample " << i << " is off the roads";
  }
  EXPECT_GT(sim.trajectory().length(), 1000.0);
  EXPECT_GE(countRevisits(sim.trajectory()), 1);
  const SimulatedScan scan = sim.simulate(50);
  EXPECT_GT(scan.cloud.size(), 90000u);
}

TEST(UrbanSim, FrontEndRegistrationRecoversTheTrueMotion) {
  if (!&createRegistration) {
    GTEST_SKIP() << "createRegistration (front-end) is not linked into this build yet";
  }
  const UrbanSimulator& sim = test::defaultSimulator();
  auto downsample = [](const PointCloud& in) {
    pcl::VoxelGrid<PointT> grid;
    grid.setLeafSize(0.2f, 0.2f, 0.2f);
    grid.setInputCloud(std::make_shared<PointCloud>(in));
    PointCloudPtr out = std::make_shared<PointCloud>();
    grid.filter(*out);
    return out;
  };
  for (size_t k : {100u, 700u}) {
    const auto target = downsample(sim.simulate(k).cloud);
    const auto source = downsample(sim.simulate(k + 1).cloud);
    const Eigen::Isometry3d truth =
        sim.sensorPose(sim.scanTime(k)).inverse() * sim.sensorPose(sim.scanTime(k + 1));
    auto reg = createRegistration(RegistrationParams{});
    reg->setTarget(target);
    const RegistrationResult r = reg->align(source, Eigen::Isometry3d::Identity());
    ASSERT_TRUE(r.converged) << r.message;
    const Eigen::Isometry3d err = truth.inverse() * r.transform;
    EXPECT_LT(err.translation().norm(), 0.02)
        << "scan " << k << " motion " << truth.translation().norm();
    EXPECT_LT(Eigen::AngleAxisd(err.linear()).angle() * 180 / M_PI, 0.1) << "scan " << k;
  }
}

TEST(StereoCameraSim, PairsAreDeterministicAndTheirStereoDepthsAreTheScene) {
  const UrbanSimulator& sim = test::defaultSimulator();
  const StereoCameraModel model;
  const double t = sim.scanTime(100);
  const Eigen::Isometry3d camera = kittiCameraFromLidar(sim.sensorPose(t));
  cv::Mat left, right, again_left, again_right;
  renderStereoPair(sim.scene().world, model, camera, t, 5, left, right);
  renderStereoPair(sim.scene().world, model, camera, t, 5, again_left, again_right);
  ASSERT_EQ(left.size(), cv::Size(1226, 370));
  EXPECT_EQ(cv::norm(left, again_left, cv::NORM_L1), 0.0);
  EXPECT_EQ(cv::norm(right, again_right, cv::NORM_L1), 0.0);
  // Enough texture for FAST, and the triangulated points lie on the scene: each one's ray, cast
  // into the world, hits a surface at the triangulated depth.
  const StereoFrame f = extractStereoFrame(left, right, model.camera(), StereoFeatureParams());
  ASSERT_GT(f.stereoMatches(), 300u);
  size_t on_scene = 0, checked = 0;
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    if (!f.has_depth[i] || f.points[i].z() > 30.0) continue;
    const Eigen::Vector3d ray = (camera.linear() * f.points[i]).normalized();
    RayHit hit;
    if (!sim.scene().world.castRay(camera.translation(), ray, 200.0, t, hit)) continue;
    ++checked;
    on_scene += std::abs(hit.range - f.points[i].norm()) < 0.1 * f.points[i].norm();
  }
  std::cout << "[stereo_camera_sim] " << f.stereoMatches() << " stereo points, " << on_scene
            << " of " << checked << " within 10 % of the scene's depth\n";
  // The rest lie on silhouettes (a corner mixes a near edge with the far background) or on the
  // facades' repeated windows (measured 214 of 274).
  ASSERT_GT(checked, 100u);
  EXPECT_GT(on_scene, checked * 70 / 100);
}

TEST(StereoCameraSim, StereoOdometryFollowsTheSimulatedDrive) {
  const UrbanSimulator& sim = test::defaultSimulator();
  const StereoCameraModel model;
  StereoOdometry odometry(model.camera(), StereoOdometryParams());
  const Eigen::Isometry3d first = kittiCameraFromLidar(sim.sensorPose(0.0));
  constexpr size_t kPairs = 20;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  double path = 0.0;
  Eigen::Isometry3d previous_truth = Eigen::Isometry3d::Identity();
  for (size_t i = 0; i < kPairs; ++i) {
    const double t = sim.scanTime(i);
    const Eigen::Isometry3d camera = kittiCameraFromLidar(sim.sensorPose(t));
    cv::Mat left, right;
    renderStereoPair(sim.scene().world, model, camera, t, 5, left, right);
    pose = odometry.track(left, right).pose;
    const Eigen::Isometry3d truth = first.inverse() * camera;
    path += (truth.translation() - previous_truth.translation()).norm();
    previous_truth = truth;
  }
  const Eigen::Isometry3d end = previous_truth.inverse() * pose;
  std::cout << "[stereo_camera_sim] " << kPairs << " rendered pairs, " << path << " m: end error "
            << end.translation().norm() << " m, "
            << Eigen::AngleAxisd(end.linear()).angle() * 180.0 / M_PI << " deg\n";
  EXPECT_EQ(odometry.lost(), 0u);
  EXPECT_LT(end.translation().norm(), 0.03 * path);
  EXPECT_LT(Eigen::AngleAxisd(end.linear()).angle(), 2.0 * M_PI / 180.0);
}
