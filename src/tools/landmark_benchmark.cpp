// Landmark place recognition benchmark (doc/landmarks.md).
//  1. Drives through the forest worlds (simulate_urban --world forest, 3 densities x N seeds):
//     keyframes every --spacing metres of a simulated HDL-64E drive, no odometry (place
//     recognition against every keyframe at least --gap metres back). Per keyframe: landmark
//     extraction, geometric-hierarchy query (then insertion), and Scan Context (descriptor +
//     ring-key retrieval + column-shift matching, the descriptor stage of loop_detection
//     without its registration check) in the same run. Precision, recall against ground-truth
//     revisits, ms per keyframe.
//  2. Scale: 5,000 keyframes of landmarks over 1 km^2 of intermediate forest (the thesis'
//     observation model: 90 % detection, 0.2 m noise) and queries at revisits: ms per query for
//     descriptor + query, and Scan Context's ms per query over a 5,000-keyframe database of the
//     drive scans' descriptors in the same run.
// The options: landmark_benchmark --help.
//  3. --scans DIR (KITTI .bin scans, e.g. the real drive 0005 unpacked; sensor frame): landmark
//     extraction per scan against Scan Context's descriptor of the same scan, in the same run.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/landmarks/landmark_extraction.h"
#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"
#include "osm_graph_slam/loop/scan_context.h"
#include "osm_graph_slam/sim/forest_world.h"
#include "osm_graph_slam/sim/simulator.h"
#include "support/command_line.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

struct Options {
  std::vector<uint64_t> seeds{1, 2, 3};
  std::vector<std::string> densities{"sparse", "intermediate", "dense"};
  double length = 1000.0;           ///< route length [m]
  double spacing = 4.0;             ///< keyframe spacing [m]
  double gap = 50.0;                ///< loop candidates at least this far back along the route [m]
  double revisit_radius = 8.0;      ///< a query is a ground-truth revisit within this [m]
  double sc_correct_radius = 12.0;  ///< a Scan Context match this close is correct [m]
  double gh_translation_tolerance = 1.0, gh_yaw_tolerance_deg = 3.0;
  int scale_keyframes = 5000, scale_queries = 200;
  bool drives = true, scale = true;
  std::string scans_dir;  ///< --scans: extraction timing on real scans
};

struct Planar {
  Eigen::Vector2d xy;
  double yaw;
};

Planar planar(const Eigen::Isometry3d& T) {
  return {T.translation().head<2>(), std::atan2(T.linear()(1, 0), T.linear()(0, 0))};
}

/// p_j = T * p_i in 2D from two planar poses.
Eigen::Isometry2d relative(const Planar& j, const Planar& i) {
  Eigen::Isometry2d Tj = Eigen::Isometry2d::Identity(), Ti = Eigen::Isometry2d::Identity();
  Tj.translate(j.xy).rotate(Eigen::Rotation2Dd(j.yaw));
  Ti.translate(i.xy).rotate(Eigen::Rotation2Dd(i.yaw));
  return Tj.inverse() * Ti;
}

double wrap(double a) {
  return std::atan2(std::sin(a), std::cos(a));
}

struct ScCandidate {
  ScanContext sc;
};

/// Scan Context place recognition: ring-key nearest (brute force L2) then full matching.
struct ScResult {
  int keyframe = -1;
  double distance = 1.0;
};
ScResult scanContextQuery(const ScanContext& q, const std::vector<ScanContext>& db, size_t limit,
                          const ScanContextParams& params, int ring_candidates) {
  std::vector<std::pair<float, int>> ring;
  for (size_t i = 0; i < limit; ++i)
    ring.push_back({(db[i].ring_key - q.ring_key).squaredNorm(), int(i)});
  const size_t k = std::min<size_t>(ring_candidates, ring.size());
  std::partial_sort(ring.begin(), ring.begin() + k, ring.end());
  ScResult best;
  for (size_t c = 0; c < k; ++c) {
    const ScanContextMatch m = matchScanContexts(q, db[ring[c].second], params);
    if (m.distance < best.distance) {
      best.distance = m.distance;
      best.keyframe = ring[c].second;
    }
  }
  return best;
}

/// Scan Context distance thresholds reported (loop_detection's ranking cut is 0.6, followed
/// there by registration; here the descriptor alone decides).
const double kScThresholds[] = {0.20, 0.30, 0.40, 0.50, 0.60};
constexpr int kNumSc = 5;

struct DriveResult {
  std::string density;
  uint64_t seed = 0;
  int keyframes = 0, revisits = 0;
  double landmarks_mean = 0;
  int gh_accepted = 0, gh_correct = 0, gh_recalled = 0;
  int sc_accepted[kNumSc] = {}, sc_correct[kNumSc] = {}, sc_recalled[kNumSc] = {};
  double extract_ms = 0, gh_query_ms = 0, gh_insert_ms = 0, sc_descriptor_ms = 0, sc_query_ms = 0;
  double gh_translation_error = 0, gh_yaw_error_deg = 0;
  double scan_s = 0;
};

bool runDrive(const std::string& density, uint64_t seed, const Options& opt, DriveResult& r,
              std::vector<ScanContext>* sc_pool) {
  SimulationParams p;
  p.seed = seed;
  p.city.world = "forest";
  p.city.forest_density = density;
  p.clutter_enabled = false;
  p.route.length = opt.length;
  p.nav.rtk = true;
  UrbanSimulator sim;
  std::string error;
  if (!sim.build(p, &error)) {
    std::fprintf(stderr, "landmark_benchmark: %s\n", error.c_str());
    return false;
  }
  r.density = density;
  r.seed = seed;
  const LandmarkExtractionParams ext;
  LandmarkPlaceRecognizer gh;
  const ScanContextParams scp;
  std::vector<ScanContext> sc_db;
  std::vector<Planar> poses;
  std::vector<double> along;
  double last_s = -1e9;
  double landmarks_sum = 0;
  for (size_t k = 0; k < sim.numScans(); ++k) {
    const double t = sim.scanTime(k);
    const double s = sim.trajectory().at(t).s;
    if (s - last_s < opt.spacing) continue;
    last_s = s;
    const auto t_scan = Clock::now();
    const SimulatedScan scan = sim.simulate(k);
    r.scan_s += msSince(t_scan) / 1000.0;
    const Planar pose = planar(sim.sensorPose(t));
    // Earlier keyframes allowed as loop candidates.
    size_t limit = 0;
    while (limit < along.size() && along[limit] <= s - opt.gap) ++limit;
    // Ground truth: the nearest allowed keyframe.
    double nearest = 1e300;
    for (size_t j = 0; j < limit; ++j) nearest = std::min(nearest, (poses[j].xy - pose.xy).norm());
    const bool revisit = nearest <= opt.revisit_radius;
    r.revisits += revisit;

    auto t0 = Clock::now();
    const auto landmarks = extractLandmarks(scan.cloud, ext);
    r.extract_ms += msSince(t0);
    landmarks_sum += landmarks.size();
    const auto centers = landmarkCenters(landmarks);
    t0 = Clock::now();
    const LandmarkQueryResult q = gh.query(centers, limit);
    r.gh_query_ms += msSince(t0);
    if (q.found) {
      ++r.gh_accepted;
      const Eigen::Isometry2d truth = relative(poses[q.keyframe], pose);
      const double dt = (truth.translation() - q.match.transform.translation()).norm();
      const double dyaw = std::abs(wrap(Eigen::Rotation2Dd(truth.linear()).angle() -
                                        Eigen::Rotation2Dd(q.match.transform.linear()).angle()));
      const bool correct =
          dt <= opt.gh_translation_tolerance && dyaw <= opt.gh_yaw_tolerance_deg * M_PI / 180.0;
      if (correct) {
        ++r.gh_correct;
        r.gh_translation_error += dt;
        r.gh_yaw_error_deg += dyaw * 180.0 / M_PI;
        if (revisit) ++r.gh_recalled;
      } else {
        std::fprintf(stderr,
                     "  false GH loop: kf %d -> %d, %.1f m apart, transform error %.2f m %.2f deg, "
                     "inliers %d ratio %.2f\n",
                     r.keyframes, q.keyframe, (poses[q.keyframe].xy - pose.xy).norm(), dt,
                     dyaw * 180 / M_PI, q.match.inliers, q.match.inlier_ratio);
      }
    }
    t0 = Clock::now();
    gh.add(centers);
    r.gh_insert_ms += msSince(t0);

    t0 = Clock::now();
    const ScanContext sc = computeScanContext(scan.cloud, scp);
    r.sc_descriptor_ms += msSince(t0);
    t0 = Clock::now();
    const ScResult sq = scanContextQuery(sc, sc_db, limit, scp, 10);
    r.sc_query_ms += msSince(t0);
    for (int i = 0; i < kNumSc; ++i) {
      if (sq.keyframe < 0 || sq.distance > kScThresholds[i]) continue;
      ++r.sc_accepted[i];
      const bool correct = (poses[sq.keyframe].xy - pose.xy).norm() <= opt.sc_correct_radius;
      r.sc_correct[i] += correct;
      if (correct && revisit) ++r.sc_recalled[i];
    }
    sc_db.push_back(sc);
    if (sc_pool) sc_pool->push_back(sc);
    poses.push_back(pose);
    along.push_back(s);
    ++r.keyframes;
  }
  r.landmarks_mean = landmarks_sum / std::max(1, r.keyframes);
  return true;
}

double pct(int a, int b) {
  return b > 0 ? 100.0 * a / b : 0.0;
}

struct ScaleResult {
  int keyframes = 0, queries = 0, found = 0, correct = 0;
  double landmarks_mean = 0, polygons_indexed = 0;
  double insert_ms = 0, hierarchy_ms = 0, retrieval_ms = 0, verification_ms = 0, total_ms = 0;
  double sc_total_ms = 0;
};

ScaleResult runScale(const Options& opt, const std::vector<ScanContext>& sc_pool,
                     double sc_descriptor_ms) {
  ScaleResult r;
  ForestParams fp;
  forestPreset("intermediate", fp);
  fp.seed = 99;
  fp.size = 1000.0;
  fp.trail_spacing = 100.0;
  const auto trunks = forestTrunks(forestScene(fp));
  std::vector<Eigen::Vector2d> trees;
  for (const auto& t : trunks) trees.push_back(t.center);
  // Grid of trees for fast range queries.
  const double cell = 10.0;
  std::map<std::pair<int, int>, std::vector<int>> grid;
  for (size_t i = 0; i < trees.size(); ++i)
    grid[{int(std::floor(trees[i].x() / cell)), int(std::floor(trees[i].y() / cell))}].push_back(
        int(i));
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double range = 30.0;
  auto observe = [&](const Planar& at) {
    std::vector<Eigen::Vector2d> out;
    const double c = std::cos(at.yaw), s = std::sin(at.yaw);
    const int cx = int(std::floor(at.xy.x() / cell)), cy = int(std::floor(at.xy.y() / cell));
    const int reach = int(std::ceil(range / cell));
    for (int x = cx - reach; x <= cx + reach; ++x)
      for (int y = cy - reach; y <= cy + reach; ++y) {
        const auto it = grid.find({x, y});
        if (it == grid.end()) continue;
        for (int i : it->second) {
          const Eigen::Vector2d d = trees[i] - at.xy;
          if (d.norm() > range || u(rng) > 0.9) continue;  // 90 % detection
          out.emplace_back(c * d.x() + s * d.y() + noise(rng), -s * d.x() + c * d.y() + noise(rng));
        }
      }
    return out;
  };
  // Lawnmower over the square: lanes 100 m apart (on the trails' grid), keyframes every 2 m.
  std::vector<Planar> poses;
  const double half = fp.size / 2 - 40.0, lane = 100.0, step = 2.0;
  const int per_lane = int((2 * half) / step);
  for (int i = 0; i < opt.scale_keyframes; ++i) {
    const int l = i / per_lane, k = i % per_lane;
    const double x = (l % 2 == 0) ? -half + k * step : half - k * step;
    poses.push_back(
        {Eigen::Vector2d(x, -half + (l % 10) * lane + 50.0 * (l / 10)), l % 2 == 0 ? 0.0 : M_PI});
  }
  LandmarkPlaceRecognizer gh;
  double lm_sum = 0;
  auto t0 = Clock::now();
  for (const auto& p : poses) {
    const auto obs = observe(p);
    lm_sum += obs.size();
    gh.add(obs);
  }
  r.insert_ms = msSince(t0) / poses.size();
  r.keyframes = int(poses.size());
  r.landmarks_mean = lm_sum / poses.size();
  r.polygons_indexed = double(gh.numIndexedPolygons());
  // Queries: revisit a random stored keyframe 1-3 m away with a random heading.
  for (int qi = 0; qi < opt.scale_queries; ++qi) {
    const int target = int(u(rng) * poses.size()) % int(poses.size());
    const double a = u(rng) * 2 * M_PI, d = 1.0 + 2.0 * u(rng);
    const Planar at{poses[target].xy + d * Eigen::Vector2d(std::cos(a), std::sin(a)),
                    u(rng) * 2 * M_PI - M_PI};
    const auto obs = observe(at);
    t0 = Clock::now();
    const LandmarkQueryResult q = gh.query(obs, gh.size());
    r.total_ms += msSince(t0);
    r.hierarchy_ms += q.hierarchy_ms;
    r.retrieval_ms += q.retrieval_ms;
    r.verification_ms += q.verification_ms;
    ++r.queries;
    if (!q.found) continue;
    ++r.found;
    const Eigen::Isometry2d truth = relative(poses[q.keyframe], at);
    if ((truth.translation() - q.match.transform.translation()).norm() < 1.0) ++r.correct;
  }
  // Scan Context over a database of the same size from the drive descriptors (pool).
  if (!sc_pool.empty()) {
    std::vector<ScanContext> db;
    for (int i = 0; i < opt.scale_keyframes; ++i) db.push_back(sc_pool[i % sc_pool.size()]);
    const ScanContextParams scp;
    for (int qi = 0; qi < opt.scale_queries; ++qi) {
      const ScanContext& q = sc_pool[(qi * 7919) % sc_pool.size()];
      t0 = Clock::now();
      scanContextQuery(q, db, db.size(), scp, 10);
      r.sc_total_ms += msSince(t0);
    }
    r.sc_total_ms = r.sc_total_ms / opt.scale_queries + sc_descriptor_ms;
  }
  const double nq = std::max(1, r.queries);
  r.total_ms /= nq;
  r.hierarchy_ms /= nq;
  r.retrieval_ms /= nq;
  r.verification_ms /= nq;
  return r;
}

}  // namespace

/// Extraction on every .bin scan of dir, Scan Context's descriptor of the same scan as the
/// reference: ms per scan and their ratio (the two see the same clouds in the same run).
int timeRealScans(const std::string& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    if (e.path().extension() == ".bin") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  const LandmarkExtractionParams ext;
  const ScanContextParams scp;
  double extract_ms = 0.0, sc_ms = 0.0;
  size_t scans = 0, landmarks = 0;
  for (const auto& f : files) {
    PointCloud cloud;
    if (!readKittiBin(f, cloud)) continue;
    auto t0 = Clock::now();
    landmarks += extractLandmarks(cloud, ext).size();
    extract_ms += msSince(t0);
    t0 = Clock::now();
    (void)computeScanContext(cloud, scp);
    sc_ms += msSince(t0);
    ++scans;
  }
  if (scans == 0) {
    std::fprintf(stderr, "landmark_benchmark: no readable .bin scan in %s\n", dir.c_str());
    return 1;
  }
  std::printf(
      "| scans | landmarks/scan | extract ms/scan | SC descriptor ms/scan | ratio |\n"
      "|---|---|---|---|---|\n| %zu | %.1f | %.2f | %.2f | %.2f |\n",
      scans, double(landmarks) / scans, extract_ms / scans, sc_ms / scans,
      extract_ms / std::max(1e-9, sc_ms));
  return 0;
}

/// The command line into opt; an exit status when the tool should stop (--help, a usage error).
std::optional<int> parseOptions(int argc, char** argv, Options& opt) {
  tools::CommandLine cli("landmark_benchmark",
                         "Landmark place recognition (geometric hierarchy) against Scan Context "
                         "on simulated forest drives, at scale, and on real scans "
                         "(doc/landmarks.md).");
  cli.option("--seeds", "1,2,3", "the forest worlds' seeds",
             [&opt](const std::string& v) {
               opt.seeds.clear();
               for (const auto& seed : tools::splitCommaList(v)) {
                 long long n = 0;
                 if (!tools::parseInt(seed, &n) || n < 0) return "'" + seed + "' is not a seed";
                 opt.seeds.push_back(static_cast<uint64_t>(n));
               }
               return std::string();
             })
      .option("--densities", "sparse,intermediate,dense", "the forest densities",
              [&opt](const std::string& v) {
                opt.densities = tools::splitCommaList(v);
                for (const auto& d : opt.densities) {
                  ForestParams check;
                  if (d == "park" || !forestPreset(d, check)) return "unknown density '" + d + "'";
                }
                return std::string();
              })
      .option("--length", "M", "route length", &opt.length)
      .option("--spacing", "M", "keyframe spacing", &opt.spacing)
      .option("--gap", "M", "loop candidates at least this far back along the route", &opt.gap)
      .option("--scale-keyframes", "N", "keyframes of the scale test (at least 10)",
              &opt.scale_keyframes)
      .option("--scale-queries", "N", "queries of the scale test (at least 1)", &opt.scale_queries)
      .flag("--no-drives", "skip the forest drives", &opt.drives, false)
      .flag("--no-scale", "skip the scale test", &opt.scale, false)
      .option("--scans", "DIR",
              "KITTI .bin scans (sensor frame): landmark extraction against Scan Context's "
              "descriptor per scan, instead of the rest",
              &opt.scans_dir);
  if (const auto exit_code = cli.parse(argc, argv)) return exit_code;
  opt.scale_keyframes = std::max(10, opt.scale_keyframes);
  opt.scale_queries = std::max(1, opt.scale_queries);
  return std::nullopt;
}

/// The forest drives, a table row per drive and the totals per density; false when a drive
/// could not be simulated.
bool runDrives(const Options& opt, std::vector<ScanContext>* sc_pool, double* sc_descriptor_ms) {
  std::printf(
      "# Forest drives: %.0f m routes, keyframes every %.1f m, candidates >= %.0f m back, "
      "revisit = an allowed keyframe within %.0f m\n"
      "# GH correct = transform within %.1f m / %.1f deg; SC correct = match within %.0f m\n",
      opt.length, opt.spacing, opt.gap, opt.revisit_radius, opt.gh_translation_tolerance,
      opt.gh_yaw_tolerance_deg, opt.sc_correct_radius);
  std::printf(
      "| density | seed | keyframes | revisits | landmarks/kf | GH precision | GH recall | "
      "SC@0.30 P/R | SC@0.40 P/R | SC@0.50 P/R | GH t err [m] | extract ms | GH query ms | "
      "SC ms |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);
  DriveResult total;
  std::map<std::string, DriveResult> per_density;
  for (const auto& d : opt.densities)
    for (uint64_t seed : opt.seeds) {
      DriveResult r;
      if (!runDrive(d, seed, opt, r, sc_pool)) return false;
      const double n = std::max(1, r.keyframes);
      std::printf(
          "| %s | %lu | %d | %d | %.1f | %.1f %% (%d/%d) | %.1f %% (%d/%d) | %.0f/%.0f | "
          "%.0f/%.0f | %.0f/%.0f | %.2f | %.2f | %.2f | %.2f |\n",
          d.c_str(), (unsigned long)seed, r.keyframes, r.revisits, r.landmarks_mean,
          pct(r.gh_correct, r.gh_accepted), r.gh_correct, r.gh_accepted,
          pct(r.gh_recalled, r.revisits), r.gh_recalled, r.revisits,
          pct(r.sc_correct[1], r.sc_accepted[1]), pct(r.sc_recalled[1], r.revisits),
          pct(r.sc_correct[2], r.sc_accepted[2]), pct(r.sc_recalled[2], r.revisits),
          pct(r.sc_correct[3], r.sc_accepted[3]), pct(r.sc_recalled[3], r.revisits),
          r.gh_correct ? r.gh_translation_error / r.gh_correct : 0.0, r.extract_ms / n,
          r.gh_query_ms / n, (r.sc_descriptor_ms + r.sc_query_ms) / n);
      std::fflush(stdout);
      for (DriveResult* acc : {&total, &per_density[d]}) {
        acc->keyframes += r.keyframes;
        acc->revisits += r.revisits;
        acc->gh_accepted += r.gh_accepted;
        acc->gh_correct += r.gh_correct;
        acc->gh_recalled += r.gh_recalled;
        for (int i = 0; i < kNumSc; ++i) {
          acc->sc_accepted[i] += r.sc_accepted[i];
          acc->sc_correct[i] += r.sc_correct[i];
          acc->sc_recalled[i] += r.sc_recalled[i];
        }
        acc->extract_ms += r.extract_ms;
        acc->gh_query_ms += r.gh_query_ms;
        acc->gh_insert_ms += r.gh_insert_ms;
        acc->sc_descriptor_ms += r.sc_descriptor_ms;
        acc->sc_query_ms += r.sc_query_ms;
      }
    }
  per_density["all"] = total;
  *sc_descriptor_ms = total.sc_descriptor_ms / std::max(1, total.keyframes);
  std::printf("\n| set | GH precision | GH recall |");
  for (double t : kScThresholds) std::printf(" SC@%.2f precision / recall |", t);
  std::printf(" extract ms | GH query+insert ms | SC descriptor+query ms |\n|---|---|---|");
  for (int i = 0; i < kNumSc; ++i) std::printf("---|");
  std::printf("---|---|---|\n");
  for (const auto& [name, r] : per_density) {
    const double n = std::max(1, r.keyframes);
    std::printf("| %s | %.1f %% (%d/%d) | %.1f %% (%d/%d) |", name.c_str(),
                pct(r.gh_correct, r.gh_accepted), r.gh_correct, r.gh_accepted,
                pct(r.gh_recalled, r.revisits), r.gh_recalled, r.revisits);
    for (int i = 0; i < kNumSc; ++i)
      std::printf(" %.1f %% / %.1f %% |", pct(r.sc_correct[i], r.sc_accepted[i]),
                  pct(r.sc_recalled[i], r.revisits));
    std::printf(" %.2f | %.2f | %.2f |\n", r.extract_ms / n, (r.gh_query_ms + r.gh_insert_ms) / n,
                (r.sc_descriptor_ms + r.sc_query_ms) / n);
  }
  std::fflush(stdout);
  return true;
}

int main(int argc, char** argv) {
  Options opt;
  if (const auto exit_code = parseOptions(argc, argv, opt)) return *exit_code;
  if (!opt.scans_dir.empty()) return timeRealScans(opt.scans_dir);
  std::vector<ScanContext> sc_pool;
  double sc_descriptor_ms = 0.0;  // mean over the drives' keyframes
  if (opt.drives && !runDrives(opt, &sc_pool, &sc_descriptor_ms)) return 1;
  if (opt.scale) {
    const ScaleResult s = runScale(opt, sc_pool, sc_descriptor_ms);
    std::printf(
        "\n# Scale: %d keyframes over 1 km^2 of intermediate forest (%.1f landmarks each, 90 %% "
        "detection, 0.2 m noise), %.0f indexed polygons; %d revisit queries\n"
        "| insert ms/kf | query ms (hierarchy + retrieval + verification) | found | correct | SC "
        "descriptor + query ms (ring keys + 10 matches; %s) | ratio GH/SC "
        "|\n|---|---|---|---|---|---|\n"
        "| %.2f | %.2f (%.2f + %.2f + %.2f) | %d/%d | %d | %.2f | %.2f |\n",
        s.keyframes, s.landmarks_mean, s.polygons_indexed, s.queries,
        sc_pool.empty() ? "no drive descriptors: not measured" : "drive descriptors replicated",
        s.insert_ms, s.total_ms, s.hierarchy_ms, s.retrieval_ms, s.verification_ms, s.found,
        s.queries, s.correct, s.sc_total_ms, s.sc_total_ms > 0 ? s.total_ms / s.sc_total_ms : 0.0);
  }
  return 0;
}
