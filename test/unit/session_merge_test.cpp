// Many drives, one map (slam/session_merge.h): drives of one known world joined into one graph.
// Shared buildings average the drives' GNSS biases; inter-session loops join drives of one
// street, and a drive whose fixes put it on the wrong street gets no loop.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/osm/building_set.h"
#include "osm_graph_slam/sim/synthetic_world.h"
#include "osm_graph_slam/slam/session_merge.h"
#include "street_drive.h"

using namespace osm_graph_slam;

namespace {

const Eigen::Vector3d kOrigin(49.0, 8.4, 100.0);

/// A dump of a drive through `truth` (x, y, yaw) with exact odometry and fixes off by `bias`.
GraphDump driveDump(const std::vector<Eigen::Vector3d>& truth, const Eigen::Vector2d& bias,
                    double first_stamp) {
  GraphDump dump;
  dump.origin = kOrigin;
  dump.initial_heading = truth.front().z();
  const Eigen::Isometry3d start =
      isometryFromPlanar(Pose2(truth[0].x(), truth[0].y(), truth[0].z()));
  double accum = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    const Eigen::Isometry3d pose =
        isometryFromPlanar(Pose2(truth[k].x(), truth[k].y(), truth[k].z()));
    if (k > 0) accum += (truth[k] - truth[k - 1]).head<2>().norm();
    KeyframeInput kf;
    kf.id = k;
    kf.stamp = first_stamp + k;
    kf.odom_pose = start.inverse() * pose;  // odometry starts at its own origin
    kf.accum_distance = accum;
    kf.odom_fitness = 0.05;
    kf.gnss_position = truth[k].head<2>() + bias;
    dump.keyframes.push_back(kf);
  }
  return dump;
}

// --- loops between drives: a ray-cast town -------------------------------------------------

struct Town {
  SyntheticWorld world = makeLoopTown(160.0, 100.0, 23.0, 11);
  SyntheticLidarParams lidar;
};

const Town& town() {
  static const Town t;
  return t;
}

/// The first street of the town (y = 0, x from 10 to 150), every 4 m, `lateral` m to the left.
std::vector<Eigen::Vector3d> firstStreet(double offset, double lateral) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : loopTownRoute(160.0, 100.0, 0.0, 4.0, offset, lateral))
    if (p.x() > 10.0 && p.x() < 150.0 && std::abs(p.y() - lateral) < 1e-6) out.push_back(p);
  return out;
}

/// The opposite street (y = 100), driven west to east like the first one.
std::vector<Eigen::Vector3d> oppositeStreet() {
  std::vector<Eigen::Vector3d> out = firstStreet(0.0, 0.0);
  for (auto& p : out) p.y() = 100.0;
  return out;
}

void addClouds(GraphDump& dump, const std::vector<Eigen::Vector3d>& truth, uint32_t seed) {
  for (size_t k = 0; k < truth.size(); ++k)
    dump.keyframes[k].cloud = simulateSyntheticScan(town().world, truth[k].head<2>(), truth[k].z(),
                                                    town().lidar, seed + k);
}

GraphBackendParams noOsm() {
  GraphBackendParams p;
  p.use_osm = false;
  return p;
}

/// Mean error of session 1's keyframes relative to session 0's first keyframe, against truth.
double relativeError(const GraphBackend& backend, const std::vector<Eigen::Vector3d>& truth0,
                     const std::vector<Eigen::Vector3d>& truth1) {
  const auto keyframes = backend.keyframes();
  Eigen::Vector2d anchor = Eigen::Vector2d::Zero();
  for (const auto& kf : keyframes)
    if (kf.id == mergedKeyframeId(0, 0)) anchor = kf.map_pose.translation().head<2>();
  double sum = 0.0;
  size_t n = 0;
  for (const auto& kf : keyframes) {
    if (kf.session != 1) continue;
    const size_t k = kf.id - mergedKeyframeId(1, 0);
    const Eigen::Vector2d estimated = kf.map_pose.translation().head<2>() - anchor;
    const Eigen::Vector2d expected = truth1[k].head<2>() - truth0[0].head<2>();
    sum += (estimated - expected).norm();
    ++n;
  }
  return n ? sum / n : 1e9;
}

}  // namespace

TEST(SessionMerge, LoopsBetweenTwoDrivesOfOneStreetUndoTheirOppositeReceiverBiases) {
  const auto a = firstStreet(0.0, 0.0), b = firstStreet(2.0, 1.5);
  GraphDump dump_a = driveDump(a, {0.0, 1.2}, 1000.0), dump_b = driveDump(b, {0.0, -1.2}, 5000.0);
  addClouds(dump_a, a, 100);
  addClouds(dump_b, b, 500);
  auto merged = [&](bool loops) {
    SessionMergeParams p;
    p.inter_session_loops = loops;
    auto merge = std::make_unique<SessionMerge>(noOsm(), LoopDetectorParams(), p);
    std::string error;
    EXPECT_TRUE(merge->addSession("a", dump_a, &error)) << error;
    EXPECT_TRUE(merge->addSession("b", dump_b, &error)) << error;
    return std::make_pair(std::move(merge), SessionMerge::sessionOf(0));
  };
  auto [with_loops, unused0] = merged(true);
  const SessionMergeReport report = with_loops->merge();
  auto [without, unused1] = merged(false);
  without->merge();

  // Every accepted loop is right: the relative pose the truth gives, within registration noise.
  size_t wrong = 0;
  for (const auto& l : report.inter_session_loops) {
    ASSERT_EQ(SessionMerge::sessionOf(l.from_id), 1u);
    ASSERT_EQ(SessionMerge::sessionOf(l.to_id), 0u);
    const Eigen::Vector3d& from = b[l.from_id - mergedKeyframeId(1, 0)];
    const Eigen::Vector3d& to = a[l.to_id - mergedKeyframeId(0, 0)];
    const Pose2 truth =
        Pose2(to.x(), to.y(), to.z()).inverse() * Pose2(from.x(), from.y(), from.z());
    const Pose2 got = planarPose(l.relative_pose);
    if (std::hypot(got.x - truth.x, got.y - truth.y) > 0.2 ||
        std::abs(wrapAngle(got.theta - truth.theta)) > 0.01)
      ++wrong;
  }
  const double error_loops = relativeError(with_loops->backend(), a, b);
  const double error_alone = relativeError(without->backend(), a, b);
  std::printf(
      "[session_merge] %zu inter-session loops from %zu queries (%zu wrong); drive b "
      "relative to drive a: %.3f m by their fixes, %.3f m with the loops\n",
      report.inter_session_loops.size(), report.loop_queries, wrong, error_alone, error_loops);
  EXPECT_EQ(wrong, 0u);
  EXPECT_GE(report.inter_session_loops.size(), b.size() / 2) << "most of the street is joined";
  EXPECT_EQ(report.sessions.at(1).inter_session_loops, report.inter_session_loops.size());
  EXPECT_GT(error_alone, 1.5) << "the receivers disagree by 2.4 m";
  EXPECT_LT(error_loops, 0.25);
}

TEST(SessionMerge, ADriveWhoseFixesPutItOnTheWrongStreetGetsNoLoop) {
  // Drive b is on the opposite street, but its fixes say the first street: every candidate the
  // search finds near its fixes is a wrong place, and verification must refuse them all.
  const auto a = firstStreet(0.0, 0.0), b_true = oppositeStreet();
  GraphDump dump_a = driveDump(a, {0.0, 0.0}, 1000.0);
  GraphDump dump_b = driveDump(b_true, {0.0, -100.0}, 5000.0);
  addClouds(dump_a, a, 100);
  addClouds(dump_b, b_true, 900);
  SessionMerge merge(noOsm(), LoopDetectorParams());
  std::string error;
  ASSERT_TRUE(merge.addSession("a", dump_a, &error)) << error;
  ASSERT_TRUE(merge.addSession("b", dump_b, &error)) << error;
  const SessionMergeReport report = merge.merge();
  std::printf("[session_merge] wrong street: %zu loops from %zu queries\n",
              report.inter_session_loops.size(), report.loop_queries);
  EXPECT_EQ(report.loop_queries, b_true.size());
  EXPECT_EQ(report.inter_session_loops.size(), 0u);
}

TEST(SessionMerge, ABadSessionIsRefusedWithItsReasonAndTheOthersStillMerge) {
  const auto a = firstStreet(0.0, 0.0);
  SessionMerge merge(noOsm(), LoopDetectorParams());
  std::string error;
  EXPECT_FALSE(merge.addSession("empty", GraphDump{}, &error));
  EXPECT_NE(error.find("no keyframe"), std::string::npos) << error;
  GraphDump huge = driveDump(a, {0.0, 0.0}, 1.0);
  huge.keyframes.back().id = kSessionIdStride;
  EXPECT_FALSE(merge.addSession("huge", huge, &error));
  EXPECT_NE(error.find("beyond"), std::string::npos) << error;
  ASSERT_TRUE(merge.addSession("a", driveDump(a, {0.0, 0.0}, 1.0), &error)) << error;
  GraphDump no_origin = driveDump(a, {0.0, 0.0}, 9.0);
  no_origin.origin.reset();
  EXPECT_FALSE(merge.addSession("no origin", no_origin, &error));
  EXPECT_EQ(merge.numSessions(), 1u);
  const SessionMergeReport report = merge.merge();
  EXPECT_EQ(report.keyframes, a.size());
  EXPECT_EQ(merge.backend().numKeyframes(), a.size());
  EXPECT_EQ(merge.backend().missingKeyframes(), 0u);
}

// --- shared buildings: the street of the back-end tests -------------------------------------

namespace {

const test::StreetDrive& street() {
  static const test::StreetDrive d(36);
  return d;
}

GraphDump streetDump(const Eigen::Vector2d& bias, double first_stamp,
                     const std::vector<Building>& prior) {
  std::vector<Eigen::Vector3d> truth;
  for (const Pose2& p : street().true_poses) truth.emplace_back(p.x, p.y, p.theta);
  GraphDump dump = driveDump(truth, bias, first_stamp);
  for (size_t k = 0; k < truth.size(); ++k) dump.segments[k] = street().segments[k];
  dump.buildings = prior;
  return dump;
}

GraphBackendParams streetParams() {
  GraphBackendParams p;
  p.mode = OsmMode::kNonRigid;
  p.buildings.use_shared_walls = false;  // the test street's buildings never touch
  return p;
}

/// Mean displacement of the corrected buildings' reference corners from the truth.
Eigen::Vector2d meanOffset(const std::vector<Building>& corrected) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  size_t n = 0;
  for (const auto& b : corrected)
    for (const auto& t : street().truth)
      if (t.id == b.id) {
        sum += b.reference_pose.translation() - t.reference_pose.translation();
        ++n;
      }
  return n ? Eigen::Vector2d(sum / n) : Eigen::Vector2d::Zero();
}

/// The median of the corrected buildings' position deviations (kSigmaXyTag), 0 when absent.
double medianSigma(const std::vector<Building>& corrected) {
  std::vector<double> sigmas;
  for (const auto& b : corrected)
    if (auto it = b.tags.find(kSigmaXyTag); it != b.tags.end())
      sigmas.push_back(std::stod(it->second));
  if (sigmas.empty()) return 0.0;
  std::nth_element(sigmas.begin(), sigmas.begin() + sigmas.size() / 2, sigmas.end());
  return sigmas[sigmas.size() / 2];
}

}  // namespace

TEST(SessionMerge, TwoDrivesWithOppositeReceiverBiasesPutTheSharedBuildingsBetweenNearerTheTruth) {
  const std::vector<Building> prior = street().perturbedPrior(0.3, 0.01, Pose2(0.0, 0.0, 0.0), 4);
  const GraphDump a = streetDump({0.0, 1.0}, 100.0, prior);
  const GraphDump b = streetDump({0.0, -1.0}, 900.0, prior);
  SessionMergeParams params;
  params.inter_session_loops = false;  // the shared buildings alone join the drives
  auto run = [&](std::vector<const GraphDump*> dumps) {
    SessionMerge merge(streetParams(), LoopDetectorParams(), params);
    std::string error;
    for (const GraphDump* d : dumps) EXPECT_TRUE(merge.addSession("d", *d, &error)) << error;
    const SessionMergeReport report = merge.merge();
    const std::vector<Building> corrected = merge.backend().correctedBuildings();
    return std::make_tuple(meanOffset(corrected),
                           evaluateBuildings(corrected, street().truth).mean_corner_error,
                           report.buildings_by_sessions, medianSigma(corrected));
  };
  const auto [offset_a, error_a, seen_a, sigma_a] = run({&a});
  const auto [offset_b, error_b, seen_b, sigma_b] = run({&b});
  const auto [offset_ab, error_ab, seen_ab, sigma_ab] = run({&a, &b});
  std::printf(
      "[session_merge] building offset (y) a %.3f, b %.3f, merged %.3f m; corner error "
      "a %.3f, b %.3f, merged %.3f m\n",
      offset_a.y(), offset_b.y(), offset_ab.y(), error_a, error_b, error_ab);
  EXPECT_GT(offset_a.y(), 0.3) << "drive a alone follows its receiver's bias";
  EXPECT_LT(offset_b.y(), -0.3);
  EXPECT_LT(offset_ab.y(), offset_a.y());
  EXPECT_GT(offset_ab.y(), offset_b.y());
  EXPECT_LT(std::abs(offset_ab.y()),
            0.5 * std::min(std::abs(offset_a.y()), std::abs(offset_b.y())));
  EXPECT_LT(error_ab, std::min(error_a, error_b));
  std::printf("[session_merge] median building deviation: a %.3f, b %.3f, merged %.3f m\n", sigma_a,
              sigma_b, sigma_ab);
  EXPECT_GT(sigma_a, 0.0) << "every observed building says how sure the map is of it";
  // Measured (given the trajectory): 0.200 and 0.187 m alone, 0.162 m merged.
  EXPECT_LT(sigma_ab, 0.92 * std::min(sigma_a, sigma_b)) << "two drives are surer than one";
  ASSERT_TRUE(seen_ab.count(2)) << "buildings seen by both drives";
  EXPECT_EQ(seen_ab.count(1) ? seen_ab.at(1) : 0u, 0u) << "both drives see the whole street";
}

TEST(SessionMerge, AnAliasedLoopIsRefusedByItsNeighboursBetweenTheSameDrives) {
  // Ten loops from drive 1 to drive 0 agree that drive 1 sits 0.5 m east and 0.2 m north of
  // where its fixes put it; one more, a facade period along the street, says 1.5 m further.
  std::vector<LoopClosureInput> loops;
  std::map<uint64_t, Eigen::Isometry3d> poses;
  std::map<uint64_t, double> stamps;
  for (uint64_t k = 0; k < 11; ++k) {
    const uint64_t from = mergedKeyframeId(1, k), to = mergedKeyframeId(0, k);
    Eigen::Isometry3d to_pose = Eigen::Isometry3d::Identity();
    to_pose.translation() = Eigen::Vector3d(4.0 * k, 0.0, 0.0);
    Eigen::Isometry3d from_pose = to_pose;
    from_pose.translation().y() += 1.0;
    poses[to] = to_pose;
    poses[from] = from_pose;
    stamps[from] = 100.0 + k;
    LoopClosureInput l;
    l.from_id = from;
    l.to_id = to;
    const double noise = 0.05 * std::sin(3.0 * k);
    l.relative_pose.translation() =
        Eigen::Vector3d(0.5 + noise + (k == 6 ? 1.5 : 0.0), 1.2 - noise, 0.0);
    loops.push_back(l);
  }
  // A loop to another drive has no neighbours to be judged by: kept.
  LoopClosureInput lone = loops.front();
  lone.to_id = mergedKeyframeId(2, 0);
  poses[lone.to_id] = poses[loops.front().to_id];
  loops.push_back(lone);
  const std::vector<size_t> refused =
      inconsistentLoops(loops, poses, stamps, InterSessionLoopParams(), &SessionMerge::sessionOf);
  ASSERT_EQ(refused.size(), 1u);
  EXPECT_EQ(refused.front(), 6u);
}
