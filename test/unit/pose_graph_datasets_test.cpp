// The five public pose graphs of ../shared/data/posegraph converge, and PoseGraph reaches the
// same χ² as the reference formulation of the Ceres documentation examples (same objective).
#include <gtest/gtest.h>

#include "osm_graph_slam/eval/reference_formulation.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

struct Dataset {
  const char* name;
  size_t vertices;
  size_t edges;
  double final_chi2;  ///< recorded optimum (g2o χ² convention, lowest id fixed)
};

void PrintTo(const Dataset& d, std::ostream* os) {
  *os << d.name;
}

class PoseGraphDataset : public ::testing::TestWithParam<Dataset> {};

TEST_P(PoseGraphDataset, ConvergesToTheReferenceOptimum) {
  const Dataset d = GetParam();
  const std::string path = test::sharedDataPath(std::string("posegraph/") + d.name + ".g2o");
  OGS_REQUIRE_SHARED_FILE(path);
  PoseGraph graph;
  const G2oReadResult read = readG2o(path, &graph);
  ASSERT_TRUE(read.ok) << read.message;
  EXPECT_EQ(graph.numVertices(), d.vertices);
  EXPECT_EQ(graph.numEdges(), d.edges);
  graph.setFixed(graph.vertexIds().front(), true);

  OptimizerOptions options;
  options.num_threads = 2;
  const ReferenceSolveResult ref = solveReferenceFormulation(graph, options);
  ASSERT_TRUE(ref.ok) << ref.message;
  const OptimizationResult ours = graph.optimize(INT_MAX, options);
  ASSERT_EQ(ours.termination, TerminationReason::kConverged) << ours.message;
  EXPECT_NEAR(ours.initial_chi2, ref.initial_chi2, 1e-9 * ref.initial_chi2);
  EXPECT_LT(ours.final_chi2, 0.1 * ours.initial_chi2);  // intel: 552 -> 45
  EXPECT_NEAR(ours.final_chi2, ref.final_chi2, 1e-4 * ref.final_chi2);
  EXPECT_NEAR(ours.final_chi2, d.final_chi2, 1e-4 * d.final_chi2);
  EXPECT_NEAR(graph.chi2(), ours.final_chi2, 1e-9 * ours.final_chi2);
  std::cout << "[          ] " << d.name << ": chi2 " << ours.initial_chi2 << " -> "
            << ours.final_chi2 << " in " << ours.iterations << " iterations, " << ours.time_ms
            << " ms (reference " << ref.final_chi2 << ", " << ref.time_ms << " ms)\n";
}

INSTANTIATE_TEST_SUITE_P(SharedData, PoseGraphDataset,
                         ::testing::Values(Dataset{"intel", 1728, 2512, 45.004724},
                                           Dataset{"manhattan", 3500, 5453, 3549.036842},
                                           Dataset{"kitti_07", 1101, 1106, 12.661036},
                                           Dataset{"sphere2500", 2500, 4949, 727.149669},
                                           Dataset{"parking-garage", 1661, 6275, 1.238691}),
                         [](const auto& info) {
                           std::string n = info.param.name;
                           for (char& c : n) c = std::isalnum(c) ? c : '_';
                           return n;
                         });

}  // namespace
}  // namespace osm_graph_slam
