// The simulator's tracker-breaking inputs: manoeuvres (sharp turn, three-point U-turn, stop-and-go,
// dead end, long straight) in the trajectory, and scans dropped from the written drive (the gap
// must reach the KITTI raw reader and kitti2bag's bag).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "osm_graph_slam/common/geometry2d.h"
#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/sim/simulator.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

constexpr double kDeg = M_PI / 180.0;

/// The procedural city without clutter (fast to build) and a short route.
SimulationParams city(uint64_t seed, const std::string& manoeuvres, double length = 300.0) {
  SimulationParams p;
  p.seed = seed;
  p.clutter_enabled = false;
  p.route.length = length;
  std::string error;
  EXPECT_TRUE(parseManoeuvreList(manoeuvres, p.route.manoeuvres, &error)) << error;
  return p;
}

double distanceToRoads(const Scene& scene, const Eigen::Vector2d& q) {
  double best = 1e18;
  for (const auto& r : scene.roads) {
    for (size_t k = 0; k + 1 < r.size(); ++k) {
      const Eigen::Vector2d e = r[k + 1] - r[k];
      const double t = std::clamp((q - r[k]).dot(e) / std::max(e.squaredNorm(), 1e-12), 0.0, 1.0);
      best = std::min(best, (r[k] + t * e - q).norm());
    }
  }
  return best;
}

/// Largest distance of the trajectory (every 1 m of path) from the road centre lines.
double maxDistanceToRoads(const UrbanSimulator& sim) {
  double worst = 0.0, next = 0.0;
  for (const auto& s : sim.trajectory().samples()) {
    if (s.s < next) continue;
    next = s.s + 1.0;
    worst = std::max(worst, distanceToRoads(sim.scene(), s.position));
  }
  return worst;
}

std::vector<ManoeuvreEvent> eventsOf(const Trajectory& traj, const std::string& type) {
  std::vector<ManoeuvreEvent> out;
  for (const auto& e : traj.manoeuvres()) {
    if (e.type == type) out.push_back(e);
  }
  return out;
}

/// The first sample at or after time t.
const TrajectoryState& sampleAtTime(const Trajectory& traj, double t) {
  const auto& v = traj.samples();
  auto it = std::lower_bound(v.begin(), v.end(), t,
                             [](const TrajectoryState& st, double x) { return st.t < x; });
  return it == v.end() ? v.back() : *it;
}

/// The first sample at or after arc length s.
const TrajectoryState& sampleAt(const Trajectory& traj, double s) {
  const auto& v = traj.samples();
  auto it = std::lower_bound(v.begin(), v.end(), s,
                             [](const TrajectoryState& st, double x) { return st.s < x; });
  return it == v.end() ? v.back() : *it;
}

std::vector<std::string> lines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);) {
    if (!l.empty()) out.push_back(l);
  }
  return out;
}

}  // namespace

TEST(SimManoeuvres, ListParsing) {
  ManoeuvreParams p;
  EXPECT_TRUE(parseManoeuvreList("none", p));
  EXPECT_FALSE(p.any());
  EXPECT_EQ(manoeuvreList(p), "none");
  EXPECT_TRUE(parseManoeuvreList("all", p));
  EXPECT_EQ(manoeuvreList(p), "sharp_turn,u_turn,stop,dead_end,long_straight");
  EXPECT_TRUE(parseManoeuvreList("stop,sharp_turn", p));
  EXPECT_TRUE(p.stop && p.sharp_turn && !p.u_turn && !p.dead_end && !p.long_straight);
  std::string error;
  EXPECT_FALSE(parseManoeuvreList("stop,wheelie", p, &error));
  EXPECT_NE(error.find("wheelie"), std::string::npos);
  EXPECT_TRUE(p.stop && p.sharp_turn);  // unchanged on failure
}

// `none` is the route of before manoeuvres existed: the numbers below were computed by the route
// code of commit cc97ff3 (procedural city, seed 3, 300 m); the manoeuvre parameters do not leak.
TEST(SimManoeuvres, NoneKeepsTheRouteOfBefore) {
  SimulationParams p = city(3, "none");
  p.route.manoeuvres.sharp_turns = 7;
  p.route.manoeuvres.u_turn_radius = 2.0;
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  const Trajectory& traj = sim.trajectory();
  EXPECT_TRUE(sim.route().actions.empty());
  EXPECT_TRUE(traj.manoeuvres().empty());
  ASSERT_EQ(traj.samples().size(), 5011u);
  EXPECT_NEAR(traj.duration(), 70.219318099117601, 1e-9);
  EXPECT_NEAR(traj.length(), 500.29398584758593, 1e-9);
  const TrajectoryState& mid = traj.samples()[traj.samples().size() / 2];
  EXPECT_NEAR(mid.position.x(), -122.58969225974445, 1e-9);
  EXPECT_NEAR(mid.position.y(), 284.95514325947693, 1e-9);
  for (const auto& s : traj.samples()) ASSERT_GE(s.speed, 0.5);
  EXPECT_LT(traj.maxYawRate(), 40.0 * kDeg);
}

TEST(SimManoeuvres, SharpTurnIsSlowFastTurningThenStrongAcceleration) {
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(city(1, "sharp_turn")));
  const Trajectory& traj = sim.trajectory();
  const auto events = eventsOf(traj, "sharp_turn");
  ASSERT_EQ(events.size(), 2u);
  for (const auto& e : events) {
    // Within the corner: >= 60 deg/s at <= 3 m/s; within 15 m after it: >= 4 m/s^2.
    double peak_yaw_rate = 0.0, speed_at_peak = 0.0, accel_after = 0.0;
    for (const auto& s : traj.samples()) {
      if (s.s >= e.s_begin && s.s <= e.s_end && std::abs(s.yaw_rate) > peak_yaw_rate) {
        peak_yaw_rate = std::abs(s.yaw_rate);
        speed_at_peak = s.speed;
      }
      if (s.s > e.s_end && s.s < e.s_end + 15.0) accel_after = std::max(accel_after, s.accel);
    }
    EXPECT_GE(peak_yaw_rate, 60.0 * kDeg) << "sharp turn at " << e.t_begin << " s";
    EXPECT_LE(peak_yaw_rate, 90.0 * kDeg + 1e-9);
    EXPECT_LE(speed_at_peak, 3.0);
    EXPECT_GT(speed_at_peak, 1.0);
    EXPECT_GE(accel_after, 4.0) << "sharp turn at " << e.t_begin << " s";
    // A 90 deg corner (60-120 deg).
    const double turn =
        std::abs(wrapAngle(sampleAt(traj, e.s_end).yaw - sampleAt(traj, e.s_begin).yaw));
    EXPECT_GT(turn, 55.0 * kDeg);
    EXPECT_LT(turn, 125.0 * kDeg);
  }
  EXPECT_LE(traj.maxAccel(), 5.0 + 1e-6);
  EXPECT_LE(traj.maxLateralAccel(), 3.0 + 1e-6);
  EXPECT_LT(maxDistanceToRoads(sim), 3.5);
}

TEST(SimManoeuvres, UTurnTurnsAroundWithinAFewMetres) {
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(city(2, "u_turn")));
  const Trajectory& traj = sim.trajectory();
  const auto events = eventsOf(traj, "u_turn");
  ASSERT_EQ(events.size(), 1u);
  const ManoeuvreEvent& e = events.front();
  EXPECT_LE(e.s_end - e.s_begin, 15.0);
  const TrajectoryState& a = sampleAtTime(traj, e.t_begin);
  const TrajectoryState& b = sampleAtTime(traj, e.t_end);
  EXPECT_GT(std::abs(wrapAngle(b.yaw - a.yaw)), 178.0 * kDeg);
  EXPECT_LT((b.position - a.position).norm(), 0.05);  // back on the street, heading reversed
  // Reverses (a three-point turn), stops at each change of direction, stays on the street.
  double min_speed = 0.0;
  int stops = 0;
  for (size_t i = 1; i < traj.samples().size(); ++i) {
    const TrajectoryState& s = traj.samples()[i];
    if (s.t < e.t_begin - 1e-9 || s.t > e.t_end + 1e-9) continue;
    min_speed = std::min(min_speed, s.speed);
    if (s.speed == 0.0 && traj.samples()[i - 1].speed != 0.0) ++stops;
    EXPECT_LT(distanceToRoads(sim.scene(), s.position), 0.5 * 4.5 + 0.01);
    if ((s.speed > 0.0 && s.accel > 0.0) || (s.speed < 0.0 && s.accel < 0.0)) {
      EXPECT_LE(std::abs(s.accel), 1.2 + 1e-6);
    }
  }
  EXPECT_LT(min_speed, -1.0);
  EXPECT_GE(stops, 3);
  EXPECT_LT(maxDistanceToRoads(sim), 3.5);
  // The scans see the reversal: the sensor moves backwards between two scans in the turn.
  bool backwards = false;
  for (double t = e.t_begin; t + 0.1 < e.t_end; t += 0.1) {
    const Eigen::Isometry3d d = sim.basePose(t).inverse() * sim.basePose(t + 0.1);
    backwards = backwards || d.translation().x() < -0.05;
  }
  EXPECT_TRUE(backwards);
}

TEST(SimManoeuvres, StopStandsStillForSecondsWhileScansGoOn) {
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(city(1, "stop")));
  const Trajectory& traj = sim.trajectory();
  const auto events = eventsOf(traj, "stop");
  ASSERT_EQ(events.size(), 2u);
  for (const auto& e : events) {
    EXPECT_NEAR(e.t_end - e.t_begin, 5.0, 1e-9);
    // At the 10 Hz scan times: speed 0 and the same pose for >= 2 s.
    size_t still = 0;
    const size_t k0 = size_t(std::ceil(e.t_begin * 10.0 - 1e-9));
    const Eigen::Isometry3d first = sim.sensorPose(sim.scanTime(k0));
    for (size_t k = k0; sim.scanTime(k) <= e.t_end + 1e-9; ++k) {
      EXPECT_EQ(traj.at(sim.scanTime(k)).speed, 0.0);
      EXPECT_TRUE(sim.sensorPose(sim.scanTime(k)).isApprox(first, 1e-12));
      ++still;
    }
    EXPECT_GE(still, 20u);
    // Normal braking before and acceleration after.
    EXPECT_GT(traj.at(e.t_begin - 3.0).speed, 3.0);
    EXPECT_GT(traj.at(e.t_end + 3.0).speed, 2.0);
  }
  EXPECT_LE(traj.maxAccel(), 1.2 + 1e-6);
  EXPECT_LE(traj.maxDecel(), 2.0 + 1e-6);
}

TEST(SimManoeuvres, DeadEndFallsBackToAUTurnInTheProceduralCity) {
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(city(1, "dead_end")));  // a street grid: no dead ends
  const auto events = eventsOf(sim.trajectory(), "dead_end");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_TRUE(events.front().fallback);
  EXPECT_LT(maxDistanceToRoads(sim), 3.5);
}

TEST(SimManoeuvres, DeadEndOfTheRealExtractIsDrivenInAndOut) {
  const std::string path = test::sharedDataPath("osm/2011_09_26_drive_0005_sync.osm");
  OGS_REQUIRE_SHARED_FILE(path);
  SimulationParams p = city(1, "dead_end");
  p.osm_path = path;
  UrbanSimulator sim;
  std::string error;
  ASSERT_TRUE(sim.build(p, &error)) << error;
  const Route& route = sim.route();
  ASSERT_EQ(route.manoeuvres.size(), 1u);
  const ManoeuvreEvent& e = route.manoeuvres.front();
  EXPECT_EQ(e.type, "dead_end");
  EXPECT_FALSE(e.fallback);
  EXPECT_GE(e.length, 15.0);
  // In and out the same way, through nodes outside the drivable 2-core, turning at its end.
  ASSERT_GT(e.last_waypoint, e.first_waypoint + 1);
  EXPECT_EQ(route.waypoints[e.first_waypoint], route.waypoints[e.last_waypoint]);
  int turns = 0;
  for (size_t i = e.first_waypoint + 1; i < e.last_waypoint; ++i) {
    EXPECT_EQ(route.node_ids[i], -1);
    turns += route.actions[i] == WaypointAction::kUTurn;
  }
  EXPECT_EQ(turns, 1);
  // The street is a dead end of the OSM road graph: its farthest node has one neighbour.
  const RoadGraph roads = RoadGraph::fromPolylines(sim.scene().roads);
  const size_t apex = (e.first_waypoint + e.last_waypoint) / 2;
  double nearest_leaf = 1e18;
  for (size_t i = 0; i < roads.nodes.size(); ++i) {
    if (roads.adjacency[i].size() == 1)
      nearest_leaf = std::min(nearest_leaf, (roads.nodes[i] - route.waypoints[apex]).norm());
  }
  EXPECT_LT(nearest_leaf, 0.5 * 4.5 * std::sqrt(3.0) + 1.5);
  EXPECT_LT(maxDistanceToRoads(sim), 4.0);
}

TEST(SimManoeuvres, LongStraightStartsTheDrive) {
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(city(1, "long_straight")));
  const auto events = eventsOf(sim.trajectory(), "long_straight");
  ASSERT_EQ(events.size(), 1u);
  const ManoeuvreEvent& e = events.front();
  EXPECT_EQ(e.first_waypoint, 0u);
  EXPECT_GE(e.length, 300.0);  // grid streets cross the 7 x 6 block city
  EXPECT_LE(e.length, 400.0 + 1e-9);
  const double yaw0 = sim.trajectory().samples().front().yaw;
  for (const auto& s : sim.trajectory().samples()) {
    if (s.s > e.length - 12.0) break;  // the corner fillet at its end
    EXPECT_LT(std::abs(wrapAngle(s.yaw - yaw0)), 12.0 * kDeg);
  }
}

TEST(SimManoeuvres, AllManoeuvresStayOnTheRoadsAndAreDeterministic) {
  UrbanSimulator sim, again;
  ASSERT_TRUE(sim.build(city(1, "all")));
  ASSERT_TRUE(again.build(city(1, "all")));
  const Trajectory& traj = sim.trajectory();
  for (const char* type : {"sharp_turn", "u_turn", "stop", "dead_end", "long_straight"})
    EXPECT_FALSE(eventsOf(traj, type).empty()) << type;
  EXPECT_EQ(sim.route().manoeuvres_skipped, 0);
  EXPECT_LT(maxDistanceToRoads(sim), 3.5);
  EXPECT_GE(countRevisits(traj), 1);
  EXPECT_LT((traj.samples().back().position - traj.samples().front().position).norm(), 1.0);
  ASSERT_EQ(traj.samples().size(), again.trajectory().samples().size());
  for (size_t i = 0; i < traj.samples().size(); ++i) {
    ASSERT_EQ(traj.samples()[i].t, again.trajectory().samples()[i].t);
    ASSERT_EQ(traj.samples()[i].position, again.trajectory().samples()[i].position);
  }
  // Time runs forward, the path is continuous (10 Hz scans see at most 0.8 m of motion).
  for (size_t i = 1; i < traj.samples().size(); ++i) {
    ASSERT_GE(traj.samples()[i].t, traj.samples()[i - 1].t);
    ASSERT_LT((traj.samples()[i].position - traj.samples()[i - 1].position).norm(), 0.11);
  }
  for (double t = 0.0; t + 0.1 < traj.duration(); t += 0.1)
    ASSERT_LT((traj.at(t + 0.1).position - traj.at(t).position).norm(), 0.81);
  EXPECT_LE(traj.maxYawRate(), 90.0 * kDeg + 1e-9);
  EXPECT_LE(traj.maxAccel(), 5.0 + 1e-6);
}

TEST(SimManoeuvres, DroppedScansLeaveGapsThatTheReadersSee) {
  const fs::path dir = fs::path(::testing::TempDir()) / "ogs_sim_dropped";
  fs::remove_all(dir);
  SimulationParams p = city(4, "none");
  p.max_scans = 30;
  p.lidar.columns = 256;  // fast: the test is about which scans exist
  p.scan_drop.fraction = 0.1;
  p.scan_drop.burst_length = 5;
  p.scan_drop.burst_time = 1.2;  // scans 12..16
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  const std::vector<bool> dropped = sim.droppedScans();
  ASSERT_EQ(dropped.size(), 30u);
  EXPECT_FALSE(dropped[0]);
  for (size_t k = 12; k < 17; ++k) EXPECT_TRUE(dropped[k]) << k;
  const size_t n_dropped = size_t(std::count(dropped.begin(), dropped.end(), true));
  EXPECT_GE(n_dropped, 5u);
  EXPECT_LE(n_dropped, 5u + 9u);  // 10 % of 25 others, generously

  SimulationStats stats;
  std::string error;
  ASSERT_TRUE(sim.writeDataset(dir.string(), stats, {}, &error)) << error;
  EXPECT_EQ(stats.scans + stats.dropped_scans, 30u);
  EXPECT_EQ(stats.dropped_scans, n_dropped);

  // The KITTI raw reader: consecutive files, one stamp each, gaps in the stamps.
  KittiRawDrive drive;
  ASSERT_TRUE(openKittiRawDrive(stats.drive_dir, "", drive, &error)) << error;
  ASSERT_EQ(drive.scan_files.size(), stats.scans);
  ASSERT_EQ(drive.oxts_files.size(), stats.scans);
  char last_name[32];
  std::snprintf(last_name, sizeof(last_name), "%010zu.bin", stats.scans - 1);
  EXPECT_EQ(fs::path(drive.scan_files.back()).filename().string(), last_name);
  std::vector<size_t> kept;
  for (size_t k = 0; k < dropped.size(); ++k) {
    if (!dropped[k]) kept.push_back(k);
  }
  ASSERT_EQ(drive.scan_stamps.size(), kept.size());
  bool burst_gap = false;
  for (size_t j = 0; j < kept.size(); ++j) {
    EXPECT_EQ(drive.scan_stamps[j] - drive.scan_stamps[0], int64_t(kept[j]) * 100000000) << j;
    EXPECT_EQ(drive.oxts_stamps[j], drive.scan_stamps[j]);
    if (j && drive.scan_stamps[j] - drive.scan_stamps[j - 1] >= 600000000) burst_gap = true;
  }
  EXPECT_TRUE(burst_gap) << "5 consecutive scans missing: a stamp gap of >= 0.6 s";
  // Ground truth rows and times follow the written scans; OXTS record j is the pose at scan j.
  std::vector<Eigen::Isometry3d> gt_imu;
  ASSERT_TRUE(readKittiPoses((dir / "ground_truth" / "poses_imu.txt").string(), gt_imu));
  ASSERT_EQ(gt_imu.size(), kept.size());
  const auto times = lines(dir / "ground_truth" / "times.txt");
  ASSERT_EQ(times.size(), kept.size());
  for (size_t j = 0; j < kept.size(); ++j) {
    EXPECT_NEAR(std::stod(times[j]), sim.scanTime(kept[j]), 1e-6);
    EXPECT_TRUE(gt_imu[j].isApprox(sim.basePose(sim.scanTime(kept[j])), 1e-9)) << j;
  }
  OxtsRecord x;
  ASSERT_TRUE(readOxtsFile(drive.oxts_files.back(), x, &error)) << error;
  EXPECT_LT(std::abs(wrapAngle(x.yaw - sim.trajectory().at(sim.scanTime(kept.back())).yaw)), 0.05);
  // sim_info.json records them.
  std::ifstream info_in(dir / "sim_info.json");
  const std::string info((std::istreambuf_iterator<char>(info_in)), {});
  EXPECT_NE(info.find("\"dropped_scans\": {\"fraction\": 0.100, \"burst_length\": 5"),
            std::string::npos);
  EXPECT_NE(info.find("\"count\": " + std::to_string(n_dropped)), std::string::npos);
  EXPECT_NE(info.find("12, 13, 14, 15, 16"), std::string::npos);

  // kitti2bag and the bag reader of offline_slam --bag: the same clouds, the same gap.
  KittiRawBagOptions o;
  o.drive_dir = stats.drive_dir;
  o.bag_path = (dir / "dropped.bag").string();
  const auto r = convertKittiRawToBag(o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.clouds, kept.size());
  BagDriveReader reader;
  ASSERT_TRUE(reader.open(o.bag_path, BagDriveTopics{}, &error)) << error;
  ASSERT_EQ(reader.numClouds(), kept.size());
  for (size_t j = 0; j < kept.size(); ++j) {
    const auto cloud = reader.nextCloud();
    ASSERT_TRUE(cloud);
    EXPECT_EQ(cloud->stamp_ns, drive.scan_stamps[j]);
    EXPECT_TRUE(reader.groundTruthAt(cloud->stamp_ns, 0.001)) << j;
  }
  EXPECT_FALSE(reader.nextCloud());

  // Same seed, fewer scans: the same scans are missing (a prefix).
  SimulationParams shorter = p;
  shorter.max_scans = 20;
  UrbanSimulator sim2;
  ASSERT_TRUE(sim2.build(shorter));
  const std::vector<bool> dropped2 = sim2.droppedScans();
  for (size_t k = 0; k < 20; ++k) {
    if (k < 12 || k >= 17) {
      EXPECT_EQ(dropped2[k], dropped[k]) << k;
    }
  }
  fs::remove_all(dir);
}

TEST(SimManoeuvres, SeededBurstLiesInTheMiddleOfTheDrive) {
  SimulationParams p = city(5, "none");
  p.max_scans = 200;
  p.scan_drop.burst_length = 30;
  UrbanSimulator sim;
  ASSERT_TRUE(sim.build(p));
  const std::vector<bool> dropped = sim.droppedScans();
  const auto first = std::find(dropped.begin(), dropped.end(), true) - dropped.begin();
  EXPECT_GE(first, 60);  // within 30-70 % of the 200 scans
  EXPECT_LE(first + 30, 140);
  EXPECT_EQ(std::count(dropped.begin(), dropped.end(), true), 30);
  EXPECT_TRUE(
      std::all_of(dropped.begin() + first, dropped.begin() + first + 30, [](bool d) { return d; }));
}
