// line_benchmark: per-keyframe milliseconds of the line stage (wall points, segments, global
// matching, local matching) on real KITTI scans and on simulated keyframes with ~15 buildings,
// each with a reference measured in the same run:
//   walls    vs pcl::NormalEstimationOMP (normal_backend = pcl)
//   segments vs a plain pcl::SACSegmentation line loop
//   matching vs the brute-force search (every edge pair, no index, no pruning, no early stop)
// The options: line_benchmark --help.
#include <pcl/ModelCoefficients.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/wall_point_extractor.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/lines/line_segment_extractor.h"
#include "osm_graph_slam/sim/wall_scan_simulator.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDeg = M_PI / 180.0;

double processCpuMs() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/// CPU time of the whole process per stage (all threads), summed over the run: on a shared,
/// loaded machine wall time also counts waiting for a core; CPU time does not.
double g_cpu_ms = 0.0;

/// Median wall time [ms]; the median run's CPU time is added to g_cpu_ms.
double medianMs(int repeat, const std::function<void()>& f) {
  std::vector<std::pair<double, double>> ms;
  for (int i = 0; i < repeat; ++i) {
    const double c0 = processCpuMs();
    const auto t0 = Clock::now();
    f();
    ms.emplace_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count(),
                    processCpuMs() - c0);
  }
  std::sort(ms.begin(), ms.end());
  g_cpu_ms = ms[ms.size() / 2].second;
  return ms[ms.size() / 2].first;
}

/// The reference: PCL's RANSAC line model, inliers removed, repeated (no clustering/refit).
size_t pclSacLineLoop(const PointCloud& walls, const LineSegmentExtractorParams& p) {
  auto rest = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (const auto& q : walls) rest->push_back(pcl::PointXYZ(q.x, q.y, 0.0f));
  pcl::SACSegmentation<pcl::PointXYZ> sac;
  sac.setModelType(pcl::SACMODEL_LINE);
  sac.setMethodType(pcl::SAC_RANSAC);
  sac.setDistanceThreshold(p.distance_threshold);
  sac.setMaxIterations(p.max_iterations);
  size_t lines = 0;
  while (int(rest->size()) > p.min_cluster_size && int(lines) < p.max_segments) {
    pcl::PointIndices::Ptr inliers(new pcl::PointIndices);
    pcl::ModelCoefficients coeff;
    sac.setInputCloud(rest);
    sac.segment(*inliers, coeff);
    if (int(inliers->indices.size()) < p.min_cluster_size) break;
    pcl::ExtractIndices<pcl::PointXYZ> extract;
    extract.setInputCloud(rest);
    extract.setIndices(inliers);
    extract.setNegative(true);
    auto next = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    extract.filter(*next);
    rest = next;
    ++lines;
  }
  return lines;
}

struct FrameRow {
  std::string name;
  size_t points = 0, wall_points = 0, segments = 0, pcl_lines = 0;
  double wall_ms = 0, wall_pcl_ms = 0, seg_ms = 0, seg_pcl_ms = 0;
  double wall_cpu_ms = 0, seg_cpu_ms = 0, match_cpu_ms = 0;  // CPU time of the median run
  bool matched = false;
  double match_ms = 0, match_brute_ms = 0, err_m = 0, err_deg = 0;
  LineMatchStats stats, brute_stats;
  double local_ms_per_building = 0;
  int local_buildings = 0;
};

struct Pipeline {
  WallPointExtractorParams wall_params;
  WallPointExtractor walls, walls_pcl;
  LineSegmentExtractor lines;
  LineMatcher matcher, brute;
  Pipeline(int threads, const WallPointExtractorParams& wp, const LineSegmentExtractorParams& lp)
      : wall_params(withThreads(wp, threads, "nanoflann")),
        walls(wall_params),
        walls_pcl(withThreads(wp, threads, "pcl")),
        lines(lp),
        brute(bruteParams()) {}
  static WallPointExtractorParams withThreads(WallPointExtractorParams p, int threads,
                                              const char* backend) {
    p.num_threads = threads;
    p.normal_backend = backend;
    return p;
  }
  static LineMatcherParams bruteParams() {
    LineMatcherParams p;
    p.brute_force = true;
    return p;
  }
};

/// Wall and segment stages of one cloud (fills the row, returns the segments).
std::vector<LineSegment2> extractStages(Pipeline& pl, const PointCloud& cloud, int repeat,
                                        FrameRow& row) {
  PointCloudPtr walls;
  row.points = cloud.size();
  WallPointStats ws;
  row.wall_ms = medianMs(repeat, [&] { walls = pl.walls.extract(cloud, &ws); });
  row.wall_cpu_ms = g_cpu_ms;
  if (std::getenv("OGS_LINE_BENCH_VERBOSE"))
    std::fprintf(stderr, "%s: cut %.2f voxel %.2f normals %.2f ms, %zu -> %zu -> %zu\n",
                 row.name.c_str(), ws.cut_ms, ws.voxel_ms, ws.normal_ms, ws.above_horizon,
                 ws.voxelized, ws.walls);
  row.wall_pcl_ms = medianMs(repeat, [&] { pl.walls_pcl.extract(cloud); });
  row.wall_points = walls->size();
  std::vector<LineSegment2> segs;
  LineSegmentStats ls;
  row.seg_ms = medianMs(repeat, [&] { segs = pl.lines.extract(*walls, &ls); });
  row.seg_cpu_ms = g_cpu_ms;
  if (std::getenv("OGS_LINE_BENCH_VERBOSE"))
    std::fprintf(stderr, "%s: segments %zu merged points, %d rounds, %d hypotheses\n",
                 row.name.c_str(), ls.merged_points, ls.lines_tried, ls.hypotheses);
  row.seg_pcl_ms = medianMs(std::max(1, repeat / 4),
                            [&] { row.pcl_lines = pclSacLineLoop(*walls, pl.lines.params()); });
  row.segments = segs.size();
  return segs;
}

void matchStage(Pipeline& pl, const std::vector<LineSegment2>& source,
                const std::vector<LineSegment2>& target, const Pose2& guess, const Pose2& truth,
                int repeat, FrameRow& row) {
  LineMatchResult r, b;
  row.match_ms = medianMs(repeat, [&] { r = pl.matcher.matchGlobal(source, target, guess); });
  row.match_cpu_ms = g_cpu_ms;
  row.match_brute_ms =
      medianMs(std::max(1, repeat / 4), [&] { b = pl.brute.matchGlobal(source, target, guess); });
  row.matched = r.success;
  row.stats = r.stats;
  row.brute_stats = b.stats;
  row.err_m = std::hypot(r.transform.x - truth.x, r.transform.y - truth.y);
  row.err_deg = std::abs(wrapAngle(r.transform.theta - truth.theta)) / kDeg;
}

struct Summary {
  double wall = 0, wall_pcl = 0, seg = 0, seg_pcl = 0, match = 0, brute = 0, local = 0;
  double wall_cpu = 0, seg_cpu = 0, match_cpu = 0;
  double max_err_m = 0, max_err_deg = 0;
  double edge_pairs_total = 0, edge_pairs_in_bounds = 0, evaluated = 0;
  int n = 0, local_n = 0, matched = 0;
};

Summary summarize(const std::vector<FrameRow>& rows) {
  Summary s;
  for (const auto& r : rows) {
    s.wall += r.wall_ms, s.wall_pcl += r.wall_pcl_ms, s.seg += r.seg_ms, s.seg_pcl += r.seg_pcl_ms;
    s.match += r.match_ms, s.brute += r.match_brute_ms;
    s.wall_cpu += r.wall_cpu_ms, s.seg_cpu += r.seg_cpu_ms, s.match_cpu += r.match_cpu_ms;
    s.edge_pairs_total += r.stats.edge_pairs_total;
    s.edge_pairs_in_bounds += r.stats.edge_pairs_in_bounds;
    s.evaluated += r.stats.hypotheses_evaluated + r.stats.line_pairs_evaluated;
    s.max_err_m = std::max(s.max_err_m, r.err_m);
    s.max_err_deg = std::max(s.max_err_deg, r.err_deg);
    s.matched += r.matched;
    if (r.local_buildings > 0) {
      s.local += r.local_ms_per_building;
      ++s.local_n;
    }
    ++s.n;
  }
  const double n = std::max(1, s.n);
  for (double* v :
       {&s.wall, &s.wall_pcl, &s.seg, &s.seg_pcl, &s.match, &s.brute, &s.wall_cpu, &s.seg_cpu,
        &s.match_cpu, &s.edge_pairs_total, &s.edge_pairs_in_bounds, &s.evaluated})
    *v /= n;
  if (s.local_n) s.local /= s.local_n;
  return s;
}

void printRows(const char* title, const std::vector<FrameRow>& rows) {
  std::printf("\n== %s ==\n", title);
  std::printf("%-22s %7s %6s %4s | %7s %7s | %7s %7s | %7s %7s | %6s %6s %5s | %6s %6s | %7s\n",
              "frame", "points", "walls", "segs", "wall", "walPCL", "segs", "sacPCL", "match",
              "brute", "pairs", "inbnd", "eval", "err_m", "errdeg", "local");
  for (const auto& r : rows)
    std::printf(
        "%-22s %7zu %6zu %4zu | %7.2f %7.2f | %7.2f %7.2f | %7.3f %7.3f | %6zu %6zu %5zu | %6.3f "
        "%6.3f | %7.3f\n",
        r.name.c_str(), r.points, r.wall_points, r.segments, r.wall_ms, r.wall_pcl_ms, r.seg_ms,
        r.seg_pcl_ms, r.match_ms, r.match_brute_ms, r.stats.edge_pairs_total,
        r.stats.edge_pairs_in_bounds, r.stats.hypotheses_evaluated + r.stats.line_pairs_evaluated,
        r.err_m, r.err_deg, r.local_ms_per_building);
  const Summary s = summarize(rows);
  std::printf(
      "mean per keyframe: walls %.2f ms (PCL normals %.2f, ratio %.1fx) | segments %.2f ms (PCL "
      "SAC "
      "loop %.2f, ratio %.1fx) | global matching %.3f ms (brute force %.3f, ratio %.1fx) | "
      "extraction + global matching %.2f ms | local %.3f ms/building | search space %.0f edge "
      "pairs -> %.0f in bounds -> %.0f evaluated | max error %.3f m %.3f deg | %d/%d matched\n",
      s.wall, s.wall_pcl, s.wall_pcl / std::max(1e-9, s.wall), s.seg, s.seg_pcl,
      s.seg_pcl / std::max(1e-9, s.seg), s.match, s.brute, s.brute / std::max(1e-9, s.match),
      s.wall + s.seg + s.match, s.local, s.edge_pairs_total, s.edge_pairs_in_bounds, s.evaluated,
      s.max_err_m, s.max_err_deg, s.matched, s.n);
  std::printf(
      "CPU time per keyframe (all threads; unaffected by waiting for a core): walls %.2f "
      "ms, segments %.2f ms, global matching %.3f ms, sum %.2f ms\n",
      s.wall_cpu, s.seg_cpu, s.match_cpu, s.wall_cpu + s.seg_cpu + s.match_cpu);
}

std::string jsonSummary(const char* key, const std::vector<FrameRow>& rows) {
  const Summary s = summarize(rows);
  std::ostringstream o;
  o << "\"" << key << "\":{\"keyframes\":" << s.n << ",\"wall_ms\":" << s.wall
    << ",\"wall_pcl_normals_ms\":" << s.wall_pcl << ",\"segment_ms\":" << s.seg
    << ",\"segment_pcl_sac_loop_ms\":" << s.seg_pcl << ",\"global_match_ms\":" << s.match
    << ",\"global_match_brute_force_ms\":" << s.brute
    << ",\"extraction_plus_global_ms\":" << s.wall + s.seg + s.match
    << ",\"wall_cpu_ms\":" << s.wall_cpu << ",\"segment_cpu_ms\":" << s.seg_cpu
    << ",\"global_match_cpu_ms\":" << s.match_cpu << ",\"local_match_ms_per_building\":" << s.local
    << ",\"edge_pairs_total\":" << s.edge_pairs_total
    << ",\"edge_pairs_in_bounds\":" << s.edge_pairs_in_bounds
    << ",\"hypotheses_evaluated\":" << s.evaluated << ",\"max_error_m\":" << s.max_err_m
    << ",\"max_error_deg\":" << s.max_err_deg << ",\"matched\":" << s.matched
    << ",\"ratio_walls_pcl\":" << s.wall_pcl / std::max(1e-9, s.wall)
    << ",\"ratio_segments_pcl\":" << s.seg_pcl / std::max(1e-9, s.seg)
    << ",\"ratio_matching_brute_force\":" << s.brute / std::max(1e-9, s.match) << "}";
  return o.str();
}

/// Real scans: consecutive pairs are matched scan-to-scan (no ground truth needed for timing;
/// KITTI 94 -> 95 is checked for accuracy by line_kitti_test).
std::vector<FrameRow> runKitti(Pipeline& pl, const std::string& data, int repeat) {
  std::vector<FrameRow> rows;
  const std::vector<std::vector<std::string>> sequences = {
      {"kitti00/000094.bin", "kitti00/000095.bin"},
      {"patchwork/000000.bin", "patchwork/000001.bin", "patchwork/000002.bin",
       "patchwork/000003.bin", "patchwork/000004.bin", "patchwork/000005.bin"}};
  for (const auto& seq : sequences) {
    std::vector<LineSegment2> previous;
    for (const auto& rel : seq) {
      PointCloud cloud;
      std::string error;
      if (!readKittiBin(data + "/" + rel, cloud, &error)) {
        std::fprintf(stderr, "skipping %s: %s\n", rel.c_str(), error.c_str());
        continue;
      }
      FrameRow row;
      row.name = rel;
      const auto segs = extractStages(pl, cloud, repeat, row);
      if (!previous.empty()) {
        matchStage(pl, segs, previous, Pose2(), Pose2(), repeat, row);
        row.err_m = row.err_deg = 0.0;  // no per-pair truth for every frame here
      }
      previous = segs;
      rows.push_back(row);
    }
  }
  return rows;
}

/// Simulated keyframes along a street with 15 buildings; the guess is off by <= 1.5 m, 10 deg.
std::vector<FrameRow> runSimulated(Pipeline& pl, int repeat) {
  std::vector<FrameRow> rows;
  const auto scene = makeStreetScene(15, 7);
  const auto map = buildingWalls(scene);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 9; ++k) {
    const Pose2 truth(-20.0 + 5.0 * k, 0.3 * u(rng), 5.0 * kDeg * u(rng));
    WallScanParams sim;
    sim.rings = 32;
    sim.seed = 100 + k;
    const PointCloudPtr scan = simulateWallScan(scene, truth, sim);
    FrameRow row;
    row.name = "sim_x" + std::to_string(int(truth.x));
    const auto segs = extractStages(pl, *scan, repeat, row);
    const Pose2 guess = truth * Pose2(1.06 * u(rng), 1.06 * u(rng), 10.0 * kDeg * u(rng));
    matchStage(pl, segs, map, guess, truth, repeat, row);
    // Local matching of every building against this keyframe (map frame).
    std::vector<LineSegment2> kf_map;
    for (const auto& s : segs) kf_map.push_back(s.transformed(truth));
    double total = 0.0;
    for (const auto& b : scene) {
      const Pose2 pose(b.outline[0].x(), b.outline[0].y(), 0.0);
      std::vector<LineSegment2> local;
      for (const auto& w : buildingWalls(b)) local.push_back(w.transformed(pose.inverse()));
      const Pose2 osm = Pose2(0.5, -0.4, 3.0 * kDeg) * pose;
      total += medianMs(repeat, [&] { pl.matcher.matchLocal(local, kf_map, osm); });
    }
    row.local_buildings = int(scene.size());
    row.local_ms_per_building = total / scene.size();
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = "../shared/data";
  int repeat = 15, threads = 2;
  WallPointExtractorParams wp;
  LineSegmentExtractorParams lp;
  bool json = false;
  tools::CommandLine cli("line_benchmark",
                         "Per-keyframe milliseconds of the line stage (wall points, segments, "
                         "global and local matching) on real KITTI scans and simulated keyframes, "
                         "each against a reference measured in the same run.");
  cli.option("--data", "DIR", "the shared data folder (KITTI scans)", &data)
      .option("--repeat", "N", "runs per stage; the median counts", &repeat)
      .option("--threads", "N", "threads of the line stage", &threads)
      .flag("--json", "print the results as JSON", &json)
      .option("--voxel", "M", "parameter study: the wall points' voxel size", &wp.voxel_size)
      .option("--k", "N", "parameter study: the wall points' normal neighbours", &wp.k_neighbors)
      .option("--merge", "M", "parameter study: the segments' merge resolution",
              &lp.merge_resolution)
      .option("--iterations", "N", "parameter study: the segments' RANSAC iterations",
              &lp.max_iterations);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  repeat = std::max(1, repeat);
  threads = std::max(1, threads);
  Pipeline pl(threads, wp, lp);
  const auto kitti = runKitti(pl, data, repeat);
  const auto sim = runSimulated(pl, repeat);
  if (json) {
    std::printf("{\"threads\":%d,\"repeat\":%d,%s,%s}\n", threads, repeat,
                jsonSummary("kitti", kitti).c_str(), jsonSummary("simulated", sim).c_str());
    return 0;
  }
  std::printf(
      "line_benchmark: %d threads, median of %d runs per stage (thesis: 464 ms extraction "
      "+ 996 ms global matching per keyframe on 8 cores; target <= 15 ms on 2 cores)\n",
      threads, repeat);
  if (kitti.empty())
    std::printf("\n(no KITTI scans under %s: real-scan rows skipped)\n", data.c_str());
  else
    printRows("real KITTI HDL-64E scans (matching: scan-to-previous-scan)", kitti);
  printRows("simulated keyframes, 15 buildings (matching: keyframe -> all building walls)", sim);
  return 0;
}
