// Honest coverage: tracking health (lost / recovered, counted once), the coverage of an estimate
// that stops short of the drive, loop recall and false loops against the ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "frontend_test_utils.h"
#include "osm_graph_slam/eval/coverage.h"
#include "osm_graph_slam/eval/loop_metrics.h"
#include "osm_graph_slam/eval/slam_evaluation.h"
#include "osm_graph_slam/io/loop_closure_file.h"
#include "osm_graph_slam/odometry/tracking_health.h"

using namespace osm_graph_slam;

namespace {

Eigen::Isometry3d at(double x, double y, double yaw = 0.0) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation() = Eigen::Vector3d(x, y, 0.0);
  return p;
}

/// A 10 Hz drive at 5 m/s along x for `seconds`.
Trajectory straightDrive(double seconds) {
  Trajectory t;
  for (int i = 0; i <= int(seconds * 10); ++i) t.push_back({i / 10.0, at(0.5 * i, 0.0)});
  return t;
}

/// Keyframes of a trajectory every `every` seconds between t0 and t1.
Trajectory keyframes(const Trajectory& truth, double t0, double t1, double every = 2.0) {
  Trajectory out;
  double next = t0;
  for (const auto& p : truth)
    if (p.stamp >= next - 1e-9 && p.stamp <= t1 + 1e-9) out.push_back(p), next = p.stamp + every;
  return out;
}

}  // namespace

TEST(TrackingHealth, LossAndRecoveryAreEachOneEventAndCounted) {
  TrackingHealth h(3.0);
  EXPECT_FALSE(h.update(0.0, test::trackResult(TrackStatus::kFirstKeyframe, true)));
  for (int i = 1; i <= 10; ++i)
    EXPECT_FALSE(h.update(i / 10.0, test::trackResult(TrackStatus::kMatched, false)));
  // From 1.1 s on every match fails: lost once the last keyframe (0.0 s) is more than 3 s old.
  int events = 0;
  std::string lost_message;
  for (int i = 11; i <= 80; ++i) {
    const auto e = h.update(i / 10.0, test::trackResult(TrackStatus::kMatchFailed, false));
    if (e) ++events, lost_message = e->message;
    if (i == 30) {
      EXPECT_EQ(h.state(), TrackingState::kOk) << "3.0 s is still within the limit";
    }
  }
  EXPECT_EQ(events, 1);
  EXPECT_EQ(h.state(), TrackingState::kLost);
  EXPECT_NE(lost_message.find("tracking lost at scan 31"), std::string::npos) << lost_message;
  EXPECT_NE(lost_message.find("fitness 3.2"), std::string::npos) << lost_message;
  EXPECT_NE(lost_message.find("21 failed matches in a row"), std::string::npos) << lost_message;
  // A new keyframe recovers it: one event naming the gap.
  const auto back = h.update(8.1, test::trackResult(TrackStatus::kMatched, true, 1));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->state, TrackingState::kOk);
  EXPECT_NE(back->message.find("after 8.1 s"), std::string::npos) << back->message;
  EXPECT_FALSE(h.update(8.2, test::trackResult(TrackStatus::kRejectedCloud, false)));

  const TrackingStats s = h.stats();
  EXPECT_EQ(s.scans, 83u);
  EXPECT_EQ(s.matched, 12u);
  EXPECT_EQ(s.failed_matches, 70u);
  EXPECT_EQ(s.rejected_scans, 1u);
  EXPECT_EQ(s.keyframes, 2u);
  EXPECT_EQ(s.lost_events, 1u);
  EXPECT_EQ(s.scans_while_lost, 50u);  // scans 31..80
  EXPECT_NEAR(s.longest_no_keyframe_s, 8.1, 1e-9);
  EXPECT_NEAR(s.first_stamp, 0.0, 1e-12);
  EXPECT_NEAR(s.last_stamp, 8.2, 1e-12);
}

TEST(TrackingHealth, AnOpenGapAtTheEndCounts) {
  TrackingHealth h(3.0);
  h.update(0.0, test::trackResult(TrackStatus::kFirstKeyframe, true));
  h.update(10.0, test::trackResult(TrackStatus::kMatchFailed, false));
  EXPECT_EQ(h.state(), TrackingState::kLost);
  EXPECT_NEAR(h.stats().longest_no_keyframe_s, 10.0, 1e-9);
  EXPECT_NEAR(h.timeSinceKeyframe(), 10.0, 1e-9);
}

TEST(Coverage, ATruncatedEstimateIsFlagged) {
  // The held-out drive of the issue: keyframes stop 64 s into a 238 s drive.
  const Trajectory truth = straightDrive(238.0);
  const Coverage full = evaluateCoverage(keyframes(truth, 0.0, 238.0), truth);
  EXPECT_NEAR(full.fraction, 1.0, 1e-9);
  EXPECT_NEAR(full.longest_gap_s, 2.0, 1e-6);
  EXPECT_NEAR(full.ground_truth_span_s, 238.0, 1e-9);

  const Coverage cut = evaluateCoverage(keyframes(truth, 0.0, 64.0), truth);
  EXPECT_NEAR(cut.estimate_span_s, 64.0, 1e-6);
  EXPECT_NEAR(cut.longest_gap_s, 174.0, 1e-6);
  EXPECT_NEAR(cut.longest_gap_m, 870.0, 1e-3);  // 5 m/s
  EXPECT_NEAR(cut.longest_gap_start, 64.0, 1e-6);
  EXPECT_NEAR(cut.fraction, 1.0 - (174.0 - 3.0) / 238.0, 1e-6);
  EXPECT_LT(cut.fraction, kCoverageWarning);

  // A 10 s hole in the middle costs its excess over the allowed 3 s.
  Trajectory holed = keyframes(truth, 0.0, 100.0);
  for (const auto& p : keyframes(truth, 110.0, 238.0)) holed.push_back(p);
  const Coverage hole = evaluateCoverage(holed, truth);
  EXPECT_NEAR(hole.longest_gap_s, 10.0, 1e-6);
  EXPECT_NEAR(hole.fraction, 1.0 - 7.0 / 238.0, 1e-6);

  // The truth written only at the run's keyframes hides the cut; the run's scan span does not.
  const Trajectory kf_truth = keyframes(truth, 0.0, 64.0);
  EXPECT_NEAR(evaluateCoverage(kf_truth, kf_truth).fraction, 1.0, 1e-9);
  CoverageOptions with_scans;
  with_scans.input_span = std::make_pair(0.0, 238.0);
  EXPECT_NEAR(evaluateCoverage(kf_truth, kf_truth, with_scans).fraction, cut.fraction, 1e-6);

  EXPECT_EQ(evaluateCoverage({}, truth).fraction, 0.0);
}

TEST(Coverage, EvaluationReportsItInJsonAndTable) {
  SlamEvaluationInput in;
  in.ground_truth = straightDrive(238.0);
  in.estimate = keyframes(in.ground_truth, 0.0, 64.0);
  in.untracked_scans = 1740;
  in.lost_events = 1;
  const SlamEvaluation e = evaluateSlam(in);
  const nlohmann::json j = nlohmann::json::parse(evaluationToJson(e));
  EXPECT_NEAR(j["coverage"]["fraction"].get<double>(), e.coverage.fraction, 1e-12);
  EXPECT_NEAR(j["coverage"]["longest_gap_s"].get<double>(), 174.0, 1e-6);
  EXPECT_EQ(j["coverage"]["untracked_scans"].get<size_t>(), 1740u);
  EXPECT_EQ(j["coverage"]["lost_events"].get<size_t>(), 1u);
  const std::string table = evaluationToTable(e);
  EXPECT_NE(table.find("WARNING: the estimate covers only 28.2 %"), std::string::npos) << table;

  in.estimate = keyframes(in.ground_truth, 0.0, 238.0);
  EXPECT_EQ(evaluationToTable(evaluateSlam(in)).find("WARNING"), std::string::npos);
}

TEST(LoopMetrics, RecallAndFalseLoopsAgainstTheTruth) {
  // A 50 m square driven twice at 5 m/s: the second lap revisits every place of the first.
  Trajectory truth;
  for (int i = 0; i <= 800; ++i) {
    const double s = std::fmod(0.5 * i, 200.0);
    const int side = int(s / 50.0);
    const double u = s - 50.0 * side;
    const double x[] = {u, 50.0, 50.0 - u, 0.0}, y[] = {0.0, u, 50.0, 50.0 - u};
    truth.push_back({i / 10.0, at(x[side], y[side], side * M_PI / 2)});
  }
  std::vector<double> stamps;
  for (const auto& p : keyframes(truth, 0.0, 80.0, 0.4)) stamps.push_back(p.stamp);

  auto loopBetween = [&](double from, double to, const Eigen::Isometry3d& error) {
    const Eigen::Isometry3d rel =
        truth[std::lround(to * 10)].pose.inverse() * truth[std::lround(from * 10)].pose;
    return StampedLoopClosure{from, to, rel * error};
  };
  std::vector<StampedLoopClosure> loops = {loopBetween(44.0, 4.0, Eigen::Isometry3d::Identity())};
  LoopEvaluation e = evaluateLoops(loops, stamps, truth);
  EXPECT_EQ(e.revisit_events, 1u);  // the whole second lap is one revisit
  EXPECT_GT(e.revisit_keyframes, 40u);
  EXPECT_EQ(e.events_closed, 1u);
  EXPECT_NEAR(e.recall, 1.0, 1e-12);
  EXPECT_EQ(e.false_loops, 0u);

  loops.push_back(loopBetween(50.0, 10.0, at(1.5, 0.0)));                    // 1.5 m off
  loops.push_back(loopBetween(52.0, 12.0, at(0.0, 0.0, 3 * M_PI / 180)));    // 3 deg off
  loops.push_back(loopBetween(54.0, 14.0, at(0.3, 0.2, 0.5 * M_PI / 180)));  // good enough
  e = evaluateLoops(loops, stamps, truth);
  EXPECT_EQ(e.accepted, 4u);
  EXPECT_EQ(e.false_loops, 2u);

  // No loop: nothing closed.
  e = evaluateLoops({}, stamps, truth);
  EXPECT_EQ(e.events_closed, 0u);
  EXPECT_EQ(e.recall, 0.0);
}

TEST(LoopClosureFile, RoundTripAndBadLinesNamed) {
  const auto dir = std::filesystem::temp_directory_path() / "ogs_loop_file_test";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "loops.txt").string();
  const std::vector<StampedLoopClosure> loops = {{12.5, 3.25, at(1.0, -2.0, 0.3)},
                                                 {99.0, 1.0, at(0.0, 0.5, -1.0)}};
  ASSERT_TRUE(writeLoopClosures(path, loops));
  const LoopClosureReadResult r = readLoopClosures(path);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.loops.size(), 2u);
  EXPECT_DOUBLE_EQ(r.loops[0].from_stamp, 12.5);
  EXPECT_DOUBLE_EQ(r.loops[1].to_stamp, 1.0);
  EXPECT_TRUE(r.loops[0].relative_pose.isApprox(loops[0].relative_pose, 1e-6));

  std::ofstream(path, std::ios::app) << "1.0 2.0 nan 0 0 0 0 0 1\n";
  const LoopClosureReadResult bad = readLoopClosures(path);
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.error.find("loops.txt:4"), std::string::npos) << bad.error;
  EXPECT_FALSE(readLoopClosures((dir / "missing.txt").string()).ok);
  std::filesystem::remove_all(dir);
}
