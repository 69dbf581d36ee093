// Loop detection on a simulated drive through a ray-cast town: a full loop around four streets
// (one of them a street of identical, evenly spaced facades and poles), then a second pass down
// the facade street in another lane. Odometry drifts (scale and heading bias).
#include <gtest/gtest.h>

#include <iostream>
#include <optional>
#include <random>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/sim/synthetic_world.h"

namespace osm_graph_slam {
namespace {

constexpr double kFacadePeriod = 14.0;

struct Drive {
  std::vector<Eigen::Isometry3d> truth;
  std::vector<LoopKeyframe> keyframes;
};

/// The drive: loop around the town every 4 m, then the facade street again 1.5 m to the left,
/// 2 m out of step and with a few degrees of heading jitter.
const Drive& drive() {
  static const Drive d = [] {
    Drive out;
    const SyntheticWorld world = makeLoopTown(200.0, 120.0, kFacadePeriod, 7);
    auto route = loopTownRoute(200.0, 120.0, 0.0, 4.0, 0.0, 0.0);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> jitter(-0.05, 0.05);
    for (double x = 2.0; x <= 150.0; x += 4.0) route.emplace_back(x, 1.5, jitter(rng));
    // Odometry: 0.5 % scale error and a heading bias of 0.003 deg per metre.
    Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
    double accum = 0.0;
    for (size_t i = 0; i < route.size(); ++i) {
      const Eigen::Isometry3d truth =
          isometryFromPlanar(Pose2(route[i].x(), route[i].y(), route[i].z()));
      if (i > 0) {
        Eigen::Isometry3d step = out.truth.back().inverse() * truth;
        const double length = step.translation().norm();
        accum += length;
        step.translation() *= 1.005;
        step = step * isometryFromPlanar(Pose2(0, 0, 0.0000524 * length));
        odom = odom * step;
      } else {
        odom = truth;
      }
      LoopKeyframe kf;
      kf.id = i;
      kf.odom_pose = odom;
      kf.accum_distance = accum;
      kf.cloud = simulateSyntheticScan(world, route[i].head<2>(), route[i].z(),
                                       SyntheticLidarParams(), 100 + i);
      out.truth.push_back(truth);
      out.keyframes.push_back(kf);
    }
    return out;
  }();
  return d;
}

struct PoseError {
  double translation = 0.0;
  double rotation_deg = 0.0;
};

PoseError errorOf(const DetectedLoop& loop, const Drive& d) {
  const Eigen::Isometry3d truth = d.truth[loop.to_id].inverse() * d.truth[loop.from_id];
  const Eigen::Isometry3d delta = truth.inverse() * loop.relative_pose;
  return {delta.translation().norm(), Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI};
}

bool hasTrueRevisit(const Drive& d, size_t i, double min_gap, double max_distance) {
  for (size_t j = 0; j < i; ++j) {
    if (d.keyframes[i].accum_distance - d.keyframes[j].accum_distance < min_gap) break;
    if ((d.truth[i].translation() - d.truth[j].translation()).norm() <= max_distance) return true;
  }
  return false;
}

struct DriveOutcome {
  int revisits = 0, found = 0, false_loops = 0, inaccurate = 0, accepted = 0, missed = 0;
  int aliases_rejected = 0;  ///< well-fitting registrations > 5 m from the truth, rejected
  int ambiguous = 0;         ///< candidates rejected by the correlative ambiguity test
  double max_t = 0.0, max_r = 0.0;
};

/// search_frame map: the keyframes before `at` arrive in a frame turned by 90 deg about the start
/// (the map frame before the heading was known); at keyframe `at` the back-end has the heading
/// and, with `update`, the detector is given the corrected poses of the stored keyframes.
struct FrameChange {
  size_t at = 0;
  bool update = false;
};

/// Runs the drive through a detector; prints every missed revisit with its candidates.
DriveOutcome runDrive(const LoopDetectorParams& params,
                      std::optional<FrameChange> change = std::nullopt) {
  const Drive& d = drive();
  LoopDetector detector(params);
  DriveOutcome out;
  const Eigen::Isometry3d turned = isometryFromPlanar(Pose2(0.0, 0.0, M_PI / 2));
  for (size_t i = 0; i < d.keyframes.size(); ++i) {
    LoopKeyframe keyframe = d.keyframes[i];
    if (change && i < change->at) keyframe.odom_pose = turned * keyframe.odom_pose;
    if (change && change->update && i == change->at) {
      std::vector<std::pair<uint64_t, Eigen::Isometry3d>> corrected;
      for (size_t j = 0; j < i; ++j) corrected.emplace_back(j, d.keyframes[j].odom_pose);
      EXPECT_EQ(detector.updatePoses(corrected), i);
    }
    const auto loop = detector.process(keyframe);
    const bool revisit = hasTrueRevisit(d, i, params.min_accum_distance_gap, 5.0);
    out.revisits += revisit ? 1 : 0;
    out.ambiguous += detector.lastStats().rejected_ambiguous;
    for (const auto& o : detector.lastStats().outcomes) {
      const Eigen::Isometry3d truth = d.truth[o.id].inverse() * d.truth[i];
      const double err = (truth.inverse() * o.transform).translation().norm();
      // A registration that fits well but lands a facade period (or more) away: the trap.
      const bool fits = (o.verdict == "odometry" && o.fitness <= params.max_fitness) ||
                        o.verdict == "coarse_odometry";
      if (fits && err > 5.0) ++out.aliases_rejected;
    }
    if (!loop) {
      out.missed += revisit ? 1 : 0;
      if (revisit) {
        std::cout << "   revisit keyframe " << i << " not closed: " << detector.lastStats().reason
                  << "\n";
        for (const auto& o : detector.lastStats().outcomes) {
          const Eigen::Isometry3d truth = d.truth[o.id].inverse() * d.truth[i];
          const Eigen::Isometry3d odom =
              d.keyframes[o.id].odom_pose.inverse() * d.keyframes[i].odom_pose;
          std::cout << "     candidate " << o.id << ": descriptor " << o.descriptor_distance
                    << ", result " << (truth.inverse() * o.transform).translation().norm()
                    << " m from the truth, odometry "
                    << (truth.inverse() * odom).translation().norm()
                    << " m from the truth, fitness " << o.fitness << ", ambiguity " << o.ambiguity
                    << " -> " << o.verdict << "\n";
        }
      }
      continue;
    }
    ++out.accepted;
    out.found += revisit ? 1 : 0;
    const PoseError e = errorOf(*loop, d);
    out.max_t = std::max(out.max_t, e.translation);
    out.max_r = std::max(out.max_r, e.rotation_deg);
    if (e.translation > 1.0 || e.rotation_deg > 2.0) ++out.false_loops;
    if (e.translation > 0.10 || e.rotation_deg > 0.5) {
      ++out.inaccurate;
      ADD_FAILURE() << "loop " << loop->from_id << "->" << loop->to_id << " error " << e.translation
                    << " m " << e.rotation_deg << " deg (fitness " << loop->fitness
                    << ", descriptor " << loop->descriptor_distance << ")";
    }
    EXPECT_GT(loop->information(0, 0), 0.0);
    EXPECT_GE(loop->information(0, 0), loop->information(2, 2) * 0.999);
  }
  std::cout << "[ loop_detector ] coarse " << params.coarse_method << ": keyframes "
            << d.keyframes.size() << ", true revisits " << out.revisits << ", found " << out.found
            << ", accepted " << out.accepted << ", false " << out.false_loops
            << ", well-fitting aliases rejected by odometry " << out.aliases_rejected
            << ", ambiguous rejected " << out.ambiguous << ", max error " << out.max_t << " m "
            << out.max_r << " deg\n";
  EXPECT_EQ(out.found + out.missed, out.revisits);
  return out;
}

TEST(LoopDetector, ClosesRevisitsAccuratelyWithoutFalseLoops) {
  // Default: correlative search over the odometry tolerance window, then the fine stage.
  const DriveOutcome out = runDrive(LoopDetectorParams());
  EXPECT_GE(out.revisits, 30);
  // Measured 38/39: the whole-window search also closes the facade-street revisits where a
  // coarse registration from one seed settled 3-5 m off (182, 187, 191 with coarse GICP); the
  // one miss (159) has no candidate within the descriptor distance.
  EXPECT_GE(out.found, static_cast<int>(0.95 * out.revisits));
  EXPECT_EQ(out.false_loops, 0);
  EXPECT_EQ(out.inaccurate, 0);
  EXPECT_LE(out.max_t, 0.02);
}

TEST(LoopDetector, SourceSubsetClosesTheSameRevisitsAsEveryQueryPoint) {
  // fine_max_source_points (default 2000 of ~4,200 query points) against 0 (all, the old).
  LoopDetectorParams all_points;
  all_points.fine_max_source_points = 0;
  const DriveOutcome full = runDrive(all_points);
  const DriveOutcome subset = runDrive(LoopDetectorParams());
  EXPECT_EQ(subset.found, full.found);
  EXPECT_EQ(subset.accepted, full.accepted);
  EXPECT_EQ(full.false_loops, 0);
  EXPECT_EQ(subset.false_loops, 0);
  // Measured: max error 3.0 mm (all) vs 4.1 mm (subset), both well inside the loops' 2 cm floor.
  EXPECT_LE(subset.max_t, full.max_t + 0.005);
  EXPECT_LE(subset.max_r, full.max_r + 0.05);
}

TEST(LoopDetector, CoarseGicpStageKeepsTheOdometryGuard) {
  // The previous pipeline (coarse GICP from the odometry and zero-translation seeds).
  LoopDetectorParams params;
  params.coarse_method = "gicp";
  const DriveOutcome out = runDrive(params);
  EXPECT_GE(out.revisits, 30);
  // Misses happen only in the facade street where 3-5 m of odometry drift along a periodic
  // corridor leaves registration in a wrong alias, which the odometry check then rejects.
  EXPECT_GE(out.found, static_cast<int>(0.85 * out.revisits));
  // The facade trap is real (aliases fit as well as true matches) and the guard catches it.
  EXPECT_GT(out.aliases_rejected, 5);
  EXPECT_EQ(out.ambiguous, 0) << "no correlative stage in this configuration";
  EXPECT_EQ(out.false_loops, 0);
  EXPECT_EQ(out.inaccurate, 0);
}

TEST(LoopDetector, StoredPosesFollowTheBackEndsCorrections) {
  // Every revisit of this drive returns to the first 40 keyframes (the first street).
  const FrameChange stale{40, false};
  const DriveOutcome before = runDrive(LoopDetectorParams(), stale);
  EXPECT_GE(before.revisits, 30);
  EXPECT_LE(before.found, before.revisits / 4) << "the stale frame should hide the revisits";
  const DriveOutcome after = runDrive(LoopDetectorParams(), FrameChange{40, true});
  EXPECT_GE(after.found, static_cast<int>(0.95 * after.revisits));
  EXPECT_EQ(after.false_loops, 0);
}

}  // namespace
}  // namespace osm_graph_slam
