// LoopDetector with the geometric-hierarchy candidate source (method geometric_hierarchy |
// combined, issue 24) on simulated forest drives (sim/loop_drive.h: prefiltered HDL-64E
// keyframes, drifting odometry): revisits at large heading changes closed with the true
// transform, a wrong place refused, combined never worse than Scan Context, the default unchanged.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>

#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/sim/loop_drive.h"

using namespace osm_graph_slam;

namespace {

struct DriveOutcome {
  int revisits = 0, accepted = 0, correct = 0, found = 0, by_hierarchy = 0;
  double max_heading_change_deg = 0.0;  ///< of a correct loop
  double max_error_m = 0.0, max_error_deg = 0.0;
  std::map<size_t, DetectedLoop> loops;  ///< by query keyframe
};

double yawOf(const Eigen::Isometry3d& pose) {
  return std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
}

/// Runs a drive through a detector. Revisit: an allowed keyframe (>= min_accum_distance_gap
/// back) within 5 m; correct: within 0.15 m / 1 deg of the true relative pose.
DriveOutcome runDrive(const sim::LoopDrive& d, const LoopDetectorParams& params) {
  LoopDetector detector(params, [](LogLevel, const std::string&) {});
  DriveOutcome out;
  for (size_t i = 0; i < d.keyframes.size(); ++i) {
    const auto loop = detector.process(d.keyframes[i]);
    const double s = d.keyframes[i].accum_distance;
    bool revisit = false;
    for (size_t j = 0; j < i; ++j) {
      if (s - d.keyframes[j].accum_distance < params.min_accum_distance_gap) break;
      revisit |= (d.truth[i].translation() - d.truth[j].translation()).norm() <= 5.0;
    }
    out.revisits += revisit;
    if (!loop) continue;
    ++out.accepted;
    out.by_hierarchy += loop->source == "geometric_hierarchy";
    const Eigen::Isometry3d truth = d.truth[loop->to_id].inverse() * d.truth[i];
    const Eigen::Isometry3d err = truth.inverse() * loop->relative_pose;
    const double et = err.translation().norm();
    const double er = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
    out.max_error_m = std::max(out.max_error_m, et);
    out.max_error_deg = std::max(out.max_error_deg, er);
    const bool correct = et <= 0.15 && er <= 1.0;
    if (!correct) {
      std::cout << "  wrong loop " << i << " -> " << loop->to_id << " (" << loop->source
                << "): " << et << " m, " << er << " deg\n";
      continue;
    }
    ++out.correct;
    out.found += revisit;
    out.loops[i] = *loop;
    out.max_heading_change_deg =
        std::max(out.max_heading_change_deg, std::abs(yawOf(truth)) * 180.0 / M_PI);
  }
  return out;
}

void print(const char* label, const DriveOutcome& o) {
  std::cout << label << ": " << o.revisits << " revisits, " << o.accepted << " accepted ("
            << o.by_hierarchy << " by the hierarchy), " << o.correct << " correct, " << o.found
            << " revisits found, max error " << o.max_error_m << " m " << o.max_error_deg
            << " deg, largest heading change of a correct loop " << o.max_heading_change_deg
            << " deg\n";
}

LoopDetectorParams withMethod(const std::string& method) {
  LoopDetectorParams p;
  p.method = method;
  return p;
}

/// The forest drive of these tests (simulated once).
const sim::LoopDrive& forestDrive() {
  static const sim::LoopDrive drive = [] {
    sim::LoopDriveParams p;
    p.world = "forest";
    p.forest_density = "intermediate";
    p.seed = 1;
    p.length = 400.0;
    sim::LoopDrive d;
    std::string error;
    EXPECT_TRUE(sim::simulateLoopDrive(p, d, &error)) << error;
    return d;
  }();
  return drive;
}

}  // namespace

TEST(LoopGeometricHierarchy, ForestRevisitsClosedWithTheTrueTransform) {
  const auto& d = forestDrive();
  ASSERT_GT(d.keyframes.size(), 50u);
  const DriveOutcome sc = runDrive(d, withMethod("scan_context"));
  const DriveOutcome gh = runDrive(d, withMethod("geometric_hierarchy"));
  const DriveOutcome combined = runDrive(d, withMethod("combined"));
  print("scan_context", sc);
  print("geometric_hierarchy", gh);
  print("combined", combined);
  ASSERT_GT(gh.revisits, 5);
  EXPECT_EQ(gh.accepted, gh.correct) << "a wrong loop was accepted";
  EXPECT_EQ(combined.accepted, combined.correct) << "a wrong loop was accepted";
  EXPECT_GE(gh.found, 0.8 * gh.revisits);
  EXPECT_EQ(gh.by_hierarchy, gh.accepted);
  EXPECT_GT(gh.max_heading_change_deg, 60.0);
  EXPECT_LT(gh.max_error_m, 0.15);
  // combined is never worse than Scan Context alone on the same drive.
  EXPECT_GE(combined.found, sc.found);
  for (const auto& [query, loop] : sc.loops) EXPECT_TRUE(combined.loops.count(query)) << query;
}
