// graph_benchmark: optimises a .g2o pose graph with PoseGraph and, in the same run, with the
// reference formulation of the Ceres documentation examples; prints χ², iterations, ms and the
// time ratio (text, or one JSON object with --json).
//
//   graph_benchmark <file.g2o> [options]   (the options: graph_benchmark --help)
//
// --repair-information: an edge with an indefinite information matrix (cubicle.g2o has one) is
// read with the nearest positive semi-definite matrix instead of being refused; every repair is
// reported on stderr and counted in the output ("repaired_information" in --json).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/eval/reference_formulation.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "support/command_line.h"

namespace {

using namespace osm_graph_slam;

struct Args {
  std::string file;
  bool json = false;
  int threads = 2;
  int repeat = 3;
  int max_iterations = 100;
  bool autodiff = false;
  bool verbose = false;
  bool eigen_sparse = false;
  bool repair_information = false;
  double radius = OptimizerOptions().initial_trust_region_radius;
};

/// The command line into args; an exit status when the tool should stop (--help, a usage error).
std::optional<int> parseArgs(int argc, char** argv, Args* args) {
  tools::CommandLine cli("graph_benchmark",
                         "Optimises a .g2o pose graph with PoseGraph and, in the same run, with "
                         "the reference formulation of the Ceres documentation examples; prints "
                         "chi2, iterations, ms and the time ratio.");
  cli.positional("FILE.g2o", "the pose graph", &args->file)
      .flag("--json", "print one JSON object", &args->json)
      .option("--threads", "N", "solver threads", &args->threads)
      .option("--repeat", "N", "runs of each formulation; the median counts", &args->repeat)
      .option("--max-iterations", "N", "solver iterations at most", &args->max_iterations)
      .flag("--autodiff", "automatic instead of analytic Jacobians", &args->autodiff)
      .option("--radius", "R", "the initial trust region radius", &args->radius)
      .flag("--eigen-sparse", "Eigen's sparse Cholesky instead of SuiteSparse", &args->eigen_sparse)
      .flag("--verbose", "the solver's per-iteration log", &args->verbose)
      .flag("--repair-information",
            "read an edge with an indefinite information matrix with the nearest positive "
            "semi-definite one instead of refusing it (reported on stderr and counted)",
            &args->repair_information);
  if (const auto exit_code = cli.parse(argc, argv)) return exit_code;
  if (args->threads <= 0 || args->repeat <= 0 || args->max_iterations <= 0)
    return cli.fail("--threads, --repeat and --max-iterations must be > 0");
  return std::nullopt;
}

double cpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Measured {
  double initial_chi2 = 0, final_chi2 = 0, ms = 0, cpu_ms = 0, min_ms = 0;  // medians, min
  int iterations = 0;
  std::string termination;
  bool ok = false;
};

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (const auto exit_code = parseArgs(argc, argv, &args)) return *exit_code;
  PoseGraph graph;
  G2oReadOptions read_options;
  read_options.repair_information = args.repair_information;
  const G2oReadResult read = readG2o(args.file, &graph, read_options);
  if (!read.ok) {
    std::cerr << "graph_benchmark: " << read.message << '\n';
    return 1;
  }
  for (const G2oInformationRepair& repair : read.repairs) {
    std::fprintf(stderr,
                 "graph_benchmark: %s line %d: indefinite information matrix (smallest "
                 "eigenvalue %.6g) replaced by the nearest positive semi-definite one (Frobenius "
                 "change %.6g)\n",
                 args.file.c_str(), repair.line, repair.min_eigenvalue, repair.frobenius_change);
  }
  if (read.num_repaired_information > 0) {
    std::fprintf(stderr, "graph_benchmark: %d information matrices repaired\n",
                 read.num_repaired_information);
  }
  // Gauge: like g2o, fix the lowest id when the file fixes nothing.
  int fixed_vertex = -1;
  if (read.num_fixed == 0 && graph.numVertices() > 0) {
    fixed_vertex = graph.vertexIds().front();
    graph.setFixed(fixed_vertex, true);
  }

  OptimizerOptions options;
  options.num_threads = args.threads;
  options.max_iterations = args.max_iterations;
  options.analytic_jacobians = !args.autodiff;
  options.verbose = args.verbose;
  if (args.eigen_sparse) options.sparse_library = SparseLibrary::kEigenSparse;
  options.initial_trust_region_radius = args.radius;

  Measured ours, ref;
  std::vector<double> ours_ms, ref_ms, ours_cpu, ref_cpu;
  PoseGraph ref_solution;
  std::string linear_solver;
  for (int r = 0; r < args.repeat; ++r) {
    PoseGraph copy = graph;
    double cpu_start = cpuMs();
    const OptimizationResult o = copy.optimize(INT_MAX, options);
    ours_cpu.push_back(cpuMs() - cpu_start);
    ours_ms.push_back(o.time_ms);
    ours = {o.initial_chi2,          o.final_chi2, 0.0, 0.0, 0.0, o.iterations,
            toString(o.termination), o.success};
    linear_solver = o.linear_solver;
    if (args.verbose)
      std::cerr << o.report << "ours: total " << o.time_ms << " ms, solve " << o.solve_ms
                << " ms\n";

    cpu_start = cpuMs();
    const ReferenceSolveResult s = solveReferenceFormulation(graph, options, &ref_solution);
    ref_cpu.push_back(cpuMs() - cpu_start);
    if (!s.ok) {
      std::cerr << "graph_benchmark: reference formulation failed: " << s.message << '\n';
      return 1;
    }
    ref_ms.push_back(s.time_ms);
    if (args.verbose) std::cerr << s.report << "reference: total " << s.time_ms << " ms\n";
    ref = {s.initial_chi2, s.final_chi2, 0.0, 0.0, 0.0, s.iterations, s.termination, s.ok};
  }
  ours.ms = median(ours_ms);
  ref.ms = median(ref_ms);
  ours.cpu_ms = median(ours_cpu);
  ref.cpu_ms = median(ref_cpu);
  const double cpu_ratio = ours.cpu_ms / ref.cpu_ms;
  ours.min_ms = *std::min_element(ours_ms.begin(), ours_ms.end());
  ref.min_ms = *std::min_element(ref_ms.begin(), ref_ms.end());
  const double min_ratio = ours.min_ms / ref.min_ms;
  // The reference solution scored by PoseGraph's own g2o-convention χ² (same objective check).
  const double ref_chi2_by_ours = ref_solution.chi2();
  const double ratio = ours.ms / ref.ms;
  const double chi2_rel =
      std::abs(ours.final_chi2 - ref.final_chi2) / std::max(1e-12, ref.final_chi2);

  if (args.json) {
    std::printf(
        "{\"file\": \"%s\", \"vertices\": %zu, \"edges\": %zu, \"initialised_vertices\": %d, "
        "\"repaired_information\": %d, "
        "\"threads\": %d, \"repeat\": %d, \"initial_trust_region_radius\": %g, "
        "\"linear_solver\": \"%s\", "
        "\"ours\": {\"initial_chi2\": %.10g, \"final_chi2\": %.10g, \"iterations\": %d, "
        "\"ms\": %.3f, \"min_ms\": %.3f, \"cpu_ms\": %.3f, \"termination\": \"%s\"}, "
        "\"reference\": {\"initial_chi2\": %.10g, \"final_chi2\": %.10g, \"iterations\": %d, "
        "\"ms\": %.3f, \"min_ms\": %.3f, \"cpu_ms\": %.3f, \"termination\": \"%s\", "
        "\"final_chi2_by_ours\": %.10g}, "
        "\"time_ratio_ours_over_reference\": %.4f, \"min_time_ratio_ours_over_reference\": %.4f, "
        "\"cpu_ratio_ours_over_reference\": %.4f, "
        "\"final_chi2_relative_difference\": %.3g}\n",
        args.file.c_str(), graph.numVertices(), graph.numEdges(), read.num_initialised,
        read.num_repaired_information, args.threads, args.repeat, args.radius,
        linear_solver.c_str(), ours.initial_chi2, ours.final_chi2, ours.iterations, ours.ms,
        ours.min_ms, ours.cpu_ms, ours.termination.c_str(), ref.initial_chi2, ref.final_chi2,
        ref.iterations, ref.ms, ref.min_ms, ref.cpu_ms, ref.termination.c_str(), ref_chi2_by_ours,
        ratio, min_ratio, cpu_ratio, chi2_rel);
    return 0;
  }
  std::printf(
      "%s: %zu vertices (%d initialised from edges), %zu edges (%d information matrices "
      "repaired), gauge: %s\n",
      args.file.c_str(), graph.numVertices(), read.num_initialised, graph.numEdges(),
      read.num_repaired_information,
      fixed_vertex >= 0 ? ("vertex " + std::to_string(fixed_vertex) + " fixed").c_str()
                        : "fixed in file");
  std::printf("threads %d, median of %d runs, %s, initial trust region radius %g\n", args.threads,
              args.repeat, linear_solver.c_str(), args.radius);
  std::printf("%-28s %16s %16s %6s %10s %10s  %s\n", "", "initial chi2", "final chi2", "iters",
              "wall ms", "cpu ms", "termination");
  std::printf("%-28s %16.8g %16.8g %6d %10.2f %10.2f  %s\n", "PoseGraph (analytic, SE3/SE2)",
              ours.initial_chi2, ours.final_chi2, ours.iterations, ours.ms, ours.cpu_ms,
              ours.termination.c_str());
  std::printf("%-28s %16.8g %16.8g %6d %10.2f %10.2f  %s\n", "reference (Ceres examples)",
              ref.initial_chi2, ref.final_chi2, ref.iterations, ref.ms, ref.cpu_ms,
              ref.termination.c_str());
  std::printf("reference final chi2 scored by PoseGraph: %.8g\n", ref_chi2_by_ours);
  std::printf("min wall ms: ours %.2f, reference %.2f\n", ours.min_ms, ref.min_ms);
  std::printf(
      "ratio ours/reference: wall %.3f (min %.3f), cpu %.3f   final chi2 relative difference: "
      "%.2e\n",
      ratio, min_ratio, cpu_ratio, chi2_rel);
  return 0;
}
