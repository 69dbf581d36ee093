#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "osm_graph_slam/eval/slam_evaluation.h"

using namespace osm_graph_slam;

namespace {

Trajectory line(size_t n, double offset_y) {
  Trajectory t;
  for (size_t i = 0; i < n; ++i) {
    StampedPose sp;
    sp.stamp = 0.1 * static_cast<double>(i);
    sp.pose.translation() = Eigen::Vector3d(static_cast<double>(i), offset_y, 0.0);
    t.push_back(sp);
  }
  return t;
}

Building box(int64_t id, double x, double y) {
  Building b;
  b.id = id;
  b.outline_enu = {{x, y}, {x + 8, y}, {x + 8, y + 6}, {x, y + 6}};
  return b;
}

}  // namespace

TEST(SlamEvaluation, ComparesAgainstBaselineAndBuildings) {
  SlamEvaluationInput in;
  in.ground_truth = line(100, 0.0);
  in.estimate = line(100, 0.5);
  in.baseline = line(100, 1.0);
  in.buildings_true = {box(1, 0, 10), box(2, 20, 10)};
  in.buildings_prior = {box(1, 1, 10), box(2, 19.5, 10)};  // 1 m and 0.5 m off, overlapping? no
  in.buildings_corrected = {box(1, 0.1, 10), box(2, 20, 10)};
  const SlamEvaluation e = evaluateSlam(in);
  EXPECT_NEAR(e.slam.ate.mean, 0.5, 1e-12);
  ASSERT_TRUE(e.baseline.has_value());
  EXPECT_NEAR(e.baseline->ate.mean, 1.0, 1e-12);
  ASSERT_TRUE(e.ate_change_vs_baseline.has_value());
  EXPECT_NEAR(*e.ate_change_vs_baseline, -0.5, 1e-12);
  ASSERT_TRUE(e.prior && e.corrected);
  EXPECT_NEAR(e.prior->errors.mean_corner_error, 0.75, 1e-12);
  EXPECT_NEAR(e.corrected->errors.mean_corner_error, 0.05, 1e-12);
  EXPECT_EQ(e.prior->overlapping_pairs, 0u);

  const auto doc = nlohmann::json::parse(evaluationToJson(e));
  EXPECT_NEAR(doc["slam"]["ate_m"]["mean"].get<double>(), 0.5, 1e-12);
  EXPECT_NEAR(doc["ate_change_vs_odometry"].get<double>(), -0.5, 1e-12);
  EXPECT_EQ(doc["buildings_corrected"]["matched"].get<int>(), 2);
  const std::string table = evaluationToTable(e);
  EXPECT_NE(table.find("-50.0 %"), std::string::npos) << table;
}

TEST(SlamEvaluation, EmptyInputsGiveZeroCountsNotGarbage) {
  const SlamEvaluation e = evaluateSlam(SlamEvaluationInput{});
  EXPECT_EQ(e.slam.associated, 0u);
  EXPECT_FALSE(e.baseline.has_value());
  EXPECT_FALSE(e.prior.has_value());
  EXPECT_NO_THROW(nlohmann::json::parse(evaluationToJson(e)));
}
