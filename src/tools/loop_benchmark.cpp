// Loop detection benchmark.
//  1. Per-keyframe time of each phase with 100, 1,000 and 5,000 keyframes in the database
//     (keyframes laid on a lawnmower drive over a 1 km^2 area, scans from a pool of ray-cast
//     town scans), plus the reference measured in the same run: brute-force Scan Context search
//     over the whole database vs the ring-key KD-tree retrieval.
//  2. Precision/recall and per-phase time on a simulated drive with revisits (ray-cast town
//     with a repetitive facade street, drifting odometry).
// Both run with the configured pipeline and, in the same run, with the previous one
// (--baseline-coarse gicp: coarse GICP stage from two seeds instead of the correlative search).
//  3. --candidates: the candidate sources (loop_detection `method`: scan_context,
//     geometric_hierarchy, combined) in lockstep on simulated drives through the forest worlds
//     and the procedural city (sim/loop_drive.h: prefiltered HDL-64E keyframes, drifting
//     odometry); only this part runs then.
// The options: loop_benchmark --help.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/loop/params_io.h"
#include "osm_graph_slam/sim/loop_drive.h"
#include "osm_graph_slam/sim/synthetic_world.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

/// Detector parameters of a run: defaults, --set overrides, then the variant's coarse method.
LoopDetectorParams g_params;

LoopDetectorParams paramsFor(const std::string& method, const std::string& coarse) {
  LoopDetectorParams params = g_params;
  params.registration.method = method;
  params.coarse_method = coarse;
  return params;
}

struct SizeResult {
  int size = 0;
  std::string coarse;
  double insert_ms = 0, descriptor_ms = 0, candidates_ms = 0, ranking_ms = 0, verification_ms = 0,
         total_ms = 0;
  // Parts of verification_ms.
  double prepare_ms = 0, correlative_ms = 0, coarse_ms = 0, fine_ms = 0, fine_target_ms = 0,
         overlap_ms = 0;
  double fine_registrations = 0, fine_iterations = 0;
  int ambiguous = 0;  ///< candidates rejected by the ambiguity test
  double tree_retrieval_ms = 0, brute_retrieval_ms = 0;
  double phase1_mean = 0, phase2_mean = 0, registrations_mean = 0;
  int accepted = 0, correct = 0, queries = 0;
  double max_error_m = 0, sum_error_m = 0;  ///< translation error of the correct loops
  // Reference back-end on the first reference_queries queries (same pipeline), and ours on them.
  int reference_queries = 0;
  double reference_verification_ms = 0, subset_verification_ms = 0;
};

/// Database of `size` keyframes on a lawnmower drive over 1 km x 1 km (keyframes every 2 m,
/// lanes 20 m apart) using clouds of the pool; the pool scan i was taken at pool_poses[i].
struct SizeWorkload {
  std::vector<Eigen::Isometry3d> pool_poses;  ///< where pool scan i was taken in the town
  std::vector<PointCloudConstPtr> pool;
  std::vector<PointCloudConstPtr>
      revisit_clouds;  ///< pool scan i re-taken 1 m / 0.5 m / 0.2 rad away
};

Eigen::Isometry3d lawnmowerPose(int i) {
  const double lane = 20.0, spacing = 2.0, width = 1000.0;
  const int per_lane = static_cast<int>(width / spacing);
  const int l = i / per_lane, k = i % per_lane;
  const double x = (l % 2 == 0) ? k * spacing : width - k * spacing;
  return isometryFromPlanar(Pose2(x, l * lane, l % 2 == 0 ? 0.0 : M_PI));
}

const Eigen::Isometry3d kRevisitOffset = isometryFromPlanar(Pose2(1.0, 0.5, 0.2));

std::unique_ptr<LoopDetector> buildDatabase(int size, const SizeWorkload& w,
                                            const LoopDetectorParams& params, double* insert_ms) {
  auto detector = std::make_unique<LoopDetector>(params, [](LogLevel, const std::string&) {});
  const auto start = Clock::now();
  for (int i = 0; i < size; ++i) {
    LoopKeyframe kf;
    kf.id = i;
    kf.odom_pose = lawnmowerPose(i);
    kf.accum_distance = i * 2.0;
    kf.cloud = w.pool[i % w.pool.size()];
    detector->addKeyframe(kf);
  }
  if (insert_ms) *insert_ms = msSince(start) / size;
  return detector;
}

/// Query q revisits database keyframe target(q): its scan is the pool scan re-taken at the
/// offset pose (other noise), its odometry pose the database pose times the offset.
LoopKeyframe revisitQuery(int size, int q, int target, const SizeWorkload& w) {
  LoopKeyframe kf;
  kf.id = size + q;
  kf.odom_pose = lawnmowerPose(target) * kRevisitOffset;
  // Back after a 200 m detour: the odometry tolerance (2 m + 1 % of the gap) is the drive's.
  kf.accum_distance = target * 2.0 + 200.0;
  kf.cloud = w.revisit_clouds[target % w.pool.size()];
  return kf;
}

/// Database keyframe i holds pool scan i % pool size (taken at pool_poses[...] in the town), the
/// query the re-scan of the target's pool scan at the offset: a loop is correct when its
/// relative pose is the true one between the two town poses within 10 cm / 0.5 deg.
bool correctLoop(const DetectedLoop& loop, int target, const SizeWorkload& w,
                 double* error_m = nullptr) {
  const size_t n = w.pool_poses.size();
  const Eigen::Isometry3d truth =
      w.pool_poses[loop.to_id % n].inverse() * w.pool_poses[target % n] * kRevisitOffset;
  const Eigen::Isometry3d err = truth.inverse() * loop.relative_pose;
  if (error_m) *error_m = err.translation().norm();
  return err.translation().norm() <= 0.1 &&
         Eigen::AngleAxisd(err.linear()).angle() <= 0.5 * M_PI / 180.0;
}

/// Prints a wrong loop and every verified candidate (--explain): true vs registered vs odometry.
void explainWrongLoop(const DetectedLoop& loop, int target, const LoopKeyframe& query,
                      const LoopDetector& detector, const SizeWorkload& w) {
  const size_t n = w.pool_poses.size();
  auto planar = [](const Eigen::Isometry3d& p) {
    std::ostringstream s;
    s << "(" << p.translation().x() << ", " << p.translation().y() << ", "
      << std::atan2(p.linear()(1, 0), p.linear()(0, 0)) * 180.0 / M_PI << " deg)";
    return s.str();
  };
  std::cerr << "wrong loop: query revisits " << target << " (pool " << target % n << "), accepted "
            << loop.to_id << " (pool " << loop.to_id % n << ") fitness " << loop.fitness
            << " overlap " << loop.overlap << " descriptor " << loop.descriptor_distance << "\n";
  for (const auto& o : detector.lastStats().outcomes) {
    const Eigen::Isometry3d truth =
        w.pool_poses[o.id % n].inverse() * w.pool_poses[target % n] * kRevisitOffset;
    const Eigen::Isometry3d odom = detector.entry(o.id).odom_pose.inverse() * query.odom_pose;
    std::cerr << "  candidate " << o.id << " (pool " << o.id % n << ") " << o.verdict << " desc "
              << o.descriptor_distance << " coarse " << o.coarse_fitness << " fine " << o.fitness
              << " overlap " << o.overlap << " registered " << planar(o.transform) << " truth "
              << planar(truth) << " odometry " << planar(odom) << "\n";
  }
}

/// A pipeline configuration measured side by side with the others.
struct Variant {
  std::string label;  ///< e.g. the coarse method
  LoopDetectorParams params;
};

void addQueryStats(SizeResult& out, const LoopQueryStats& s, bool in_reference_subset) {
  out.descriptor_ms += s.descriptor_ms;
  out.candidates_ms += s.candidates_ms;
  out.ranking_ms += s.ranking_ms;
  out.verification_ms += s.verification_ms;
  if (in_reference_subset) out.subset_verification_ms += s.verification_ms;
  out.prepare_ms += s.prepare_ms;
  out.correlative_ms += s.correlative_ms;
  out.coarse_ms += s.coarse_ms;
  out.fine_ms += s.fine_ms;
  out.fine_target_ms += s.fine_target_ms;
  out.overlap_ms += s.overlap_ms;
  out.fine_registrations += s.fine_registrations;
  out.fine_iterations += s.fine_iterations;
  out.ambiguous += s.rejected_ambiguous;
  out.phase1_mean += s.phase1_candidates;
  out.phase2_mean += s.phase2_candidates;
  out.registrations_mean += s.verified;
}

void averageSizeResult(SizeResult& out, int queries) {
  for (double* v :
       {&out.descriptor_ms, &out.candidates_ms, &out.ranking_ms, &out.verification_ms,
        &out.phase1_mean, &out.phase2_mean, &out.registrations_mean, &out.tree_retrieval_ms,
        &out.brute_retrieval_ms, &out.prepare_ms, &out.correlative_ms, &out.coarse_ms, &out.fine_ms,
        &out.fine_target_ms, &out.overlap_ms, &out.fine_registrations, &out.fine_iterations}) {
    *v /= queries;
  }
  out.total_ms = out.descriptor_ms + out.candidates_ms + out.ranking_ms + out.verification_ms;
}

/// Every variant answers the same queries, interleaved query by query (alternating which goes
/// first) so that the load of the shared machine falls on all of them alike. The first variant
/// is the configured pipeline: the place-recognition retrieval and the back-end reference are
/// measured for it only.
std::vector<SizeResult> benchmarkSize(int size, int queries, int reference_queries,
                                      const SizeWorkload& w, const std::vector<Variant>& variants,
                                      const std::string& reference, bool explain) {
  std::vector<SizeResult> results(variants.size());
  std::vector<std::unique_ptr<LoopDetector>> detectors;
  for (size_t v = 0; v < variants.size(); ++v) {
    results[v].size = size;
    results[v].coarse = variants[v].label;
    results[v].queries = queries;
    detectors.push_back(buildDatabase(size, w, variants[v].params, &results[v].insert_ms));
  }
  SizeResult& out = results.front();
  LoopDetector* detector = detectors.front().get();
  const LoopDetectorParams& params = detector->params();
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> pick(0, size - 1);
  std::vector<int> targets;
  for (int q = 0; q < queries; ++q) targets.push_back(pick(rng));
  for (int q = 0; q < queries; ++q) {
    const LoopKeyframe kf = revisitQuery(size, q, targets[q], w);
    for (size_t k = 0; k < variants.size(); ++k) {
      const size_t v = (q % 2 == 0) ? k : variants.size() - 1 - k;
      const auto loop = detectors[v]->detect(kf);
      addQueryStats(results[v], detectors[v]->lastStats(), q < reference_queries);
      if (loop) {
        ++results[v].accepted;
        double error_m = 0.0;
        const bool ok = correctLoop(*loop, targets[q], w, &error_m);
        results[v].correct += ok;
        if (ok) {
          results[v].max_error_m = std::max(results[v].max_error_m, error_m);
          results[v].sum_error_m += error_m;
        }
        if (!ok && explain) explainWrongLoop(*loop, targets[q], kf, *detectors[v], w);
      }
    }
    // Place-recognition retrieval: ring-key tree vs brute force over every keyframe.
    const ScanContext sc = computeScanContext(*kf.cloud, params.scan_context);
    auto start = Clock::now();
    const auto ranked = detector->rankCandidates(sc, detector->ringKeyCandidates(sc, size));
    out.tree_retrieval_ms += msSince(start);
    start = Clock::now();
    double best = 2.0;
    for (size_t i = 0; i < detector->size(); ++i) {
      best = std::min(
          best, matchScanContexts(sc, detector->entry(i).descriptor, params.scan_context).distance);
    }
    out.brute_retrieval_ms += msSince(start);
    if (best > 1.5 || ranked.size() > 1000) std::cerr << "unexpected\n";
  }
  for (auto& r : results) averageSizeResult(r, queries);
  detectors.clear();
  out.reference_queries = std::min(reference_queries, queries);
  if (reference != "none" && out.reference_queries > 0) {
    LoopDetectorParams ref_params = variants.front().params;
    ref_params.registration.method = reference;
    auto ref = buildDatabase(size, w, ref_params, nullptr);
    for (int q = 0; q < out.reference_queries; ++q) {
      ref->detect(revisitQuery(size, q, targets[q], w));
      out.reference_verification_ms += ref->lastStats().verification_ms;
    }
    out.reference_verification_ms /= out.reference_queries;
    out.subset_verification_ms /= out.reference_queries;
  }
  return results;
}

struct DriveResult {
  std::string method, coarse;
  int ambiguous = 0;
  double prepare_ms_per_query = 0, correlative_ms_per_query = 0;
  int keyframes = 0, revisits = 0, found = 0, accepted = 0, correct = 0;
  double precision = 0, recall = 0, max_error_m = 0, max_error_deg = 0;
  double sum_error_m = 0;  ///< translation error summed over the correct loops
  double descriptor_ms = 0, candidates_ms = 0, ranking_ms = 0, verification_ms = 0;
  double verification_ms_per_query = 0, registrations_per_query = 0;
  double coarse_ms_per_query = 0, fine_ms_per_query = 0, overlap_ms_per_query = 0;
  int verified_queries = 0;
  double total_ms = 0;  ///< wall time of process() (query + insertion) per keyframe
  double landmark_ms = 0, landmarks_mean = 0;  ///< extraction + hierarchy query per keyframe
  int landmark_accepted = 0;                   ///< accepted loops proposed by the hierarchy
};

/// The drive of loop_detector_test: a loop around the town every 4 m, then the facade street
/// again 1.5 m to the left; odometry with 0.5 % scale error and 0.003 deg/m heading bias.
struct Drive {
  std::vector<Eigen::Isometry3d> truth;
  std::vector<LoopKeyframe> keyframes;
};

Drive makeDrive() {
  Drive d;
  const SyntheticWorld world = makeLoopTown(200.0, 120.0, 14.0, 7);
  auto route = loopTownRoute(200.0, 120.0, 0.0, 4.0, 0.0, 0.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  for (double x = 2.0; x <= 150.0; x += 4.0) route.emplace_back(x, 1.5, jitter(rng));
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  double s = 0.0;
  for (size_t i = 0; i < route.size(); ++i) {
    d.truth.push_back(isometryFromPlanar(Pose2(route[i].x(), route[i].y(), route[i].z())));
    if (i > 0) {
      Eigen::Isometry3d step = d.truth[i - 1].inverse() * d.truth[i];
      const double len = step.translation().norm();
      s += len;
      step.translation() *= 1.005;
      odom = odom * step * isometryFromPlanar(Pose2(0, 0, 0.0000524 * len));
    } else {
      odom = d.truth[0];
    }
    LoopKeyframe kf;
    kf.id = i;
    kf.odom_pose = odom;
    kf.accum_distance = s;
    kf.cloud = simulateSyntheticScan(world, route[i].head<2>(), route[i].z(),
                                     SyntheticLidarParams(), 100 + i);
    d.keyframes.push_back(kf);
  }
  return d;
}

/// Accumulates one keyframe's outcome of a variant.
void addDriveKeyframe(DriveResult& out, const Drive& d, size_t i, const LoopQueryStats& st,
                      const std::optional<DetectedLoop>& loop, double min_gap, bool explain) {
  const double s = d.keyframes[i].accum_distance;
  out.descriptor_ms += st.descriptor_ms;
  out.candidates_ms += st.candidates_ms;
  out.ranking_ms += st.ranking_ms;
  out.verification_ms += st.verification_ms;
  if (st.verified > 0) {
    out.verification_ms_per_query += st.verification_ms;
    out.registrations_per_query += st.verified;
    out.coarse_ms_per_query += st.coarse_ms;
    out.fine_ms_per_query += st.fine_ms;
    out.overlap_ms_per_query += st.overlap_ms;
    out.prepare_ms_per_query += st.prepare_ms;
    out.correlative_ms_per_query += st.correlative_ms;
    ++out.verified_queries;
  }
  out.ambiguous += st.rejected_ambiguous;
  out.landmark_ms += st.landmark_extraction_ms + st.landmark_query_ms;
  out.landmarks_mean += st.landmarks;
  bool revisit = false;
  for (size_t j = 0; j < i && s - d.keyframes[j].accum_distance >= min_gap; ++j) {
    if ((d.truth[i].translation() - d.truth[j].translation()).norm() <= 5.0) revisit = true;
  }
  out.revisits += revisit;
  if (!loop) return;
  ++out.accepted;
  out.landmark_accepted += loop->source == "geometric_hierarchy";
  const Eigen::Isometry3d err =
      (d.truth[loop->to_id].inverse() * d.truth[i]).inverse() * loop->relative_pose;
  const double et = err.translation().norm();
  const double er = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
  out.max_error_m = std::max(out.max_error_m, et);
  out.max_error_deg = std::max(out.max_error_deg, er);
  const bool correct = et <= 0.10 && er <= 0.5;
  out.correct += correct;
  if (correct) out.sum_error_m += et;
  if (!correct && explain) {
    std::cerr << "drive [" << out.coarse << "]: wrong loop " << i << " -> " << loop->to_id
              << " error " << et << " m " << er << " deg\n";
  }
  out.found += revisit && correct;
}

void averageDriveResult(DriveResult& out, int keyframes) {
  out.keyframes = keyframes;
  out.precision = out.accepted ? static_cast<double>(out.correct) / out.accepted : 1.0;
  out.recall = out.revisits ? static_cast<double>(out.found) / out.revisits : 1.0;
  for (double* v : {&out.descriptor_ms, &out.candidates_ms, &out.ranking_ms, &out.verification_ms,
                    &out.total_ms, &out.landmark_ms, &out.landmarks_mean}) {
    *v /= out.keyframes;
  }
  if (out.verified_queries) {
    for (double* v : {&out.verification_ms_per_query, &out.registrations_per_query,
                      &out.coarse_ms_per_query, &out.fine_ms_per_query, &out.overlap_ms_per_query,
                      &out.prepare_ms_per_query, &out.correlative_ms_per_query}) {
      *v /= out.verified_queries;
    }
  }
}

/// The drive through every variant in lockstep (keyframe by keyframe, alternating the order).
std::vector<DriveResult> benchmarkDrive(const Drive& d, const std::vector<Variant>& variants,
                                        bool explain) {
  std::vector<DriveResult> results(variants.size());
  std::vector<std::unique_ptr<LoopDetector>> detectors;
  for (size_t v = 0; v < variants.size(); ++v) {
    results[v].method = variants[v].params.registration.method;
    results[v].coarse = variants[v].label;
    detectors.push_back(
        std::make_unique<LoopDetector>(variants[v].params, [](LogLevel, const std::string&) {}));
  }
  for (size_t i = 0; i < d.keyframes.size(); ++i) {
    for (size_t k = 0; k < variants.size(); ++k) {
      const size_t v = (i % 2 == 0) ? k : variants.size() - 1 - k;
      const auto start = Clock::now();
      const auto loop = detectors[v]->process(d.keyframes[i]);
      results[v].total_ms += msSince(start);
      addDriveKeyframe(results[v], d, i, detectors[v]->lastStats(), loop,
                       variants[v].params.min_accum_distance_gap, explain);
    }
  }
  for (auto& r : results) averageDriveResult(r, static_cast<int>(d.keyframes.size()));
  return results;
}

void printDrive(const DriveResult& d) {
  std::printf(
      "drive [%s, coarse %s]: %d keyframes, %d revisits, %d accepted (%d correct), precision "
      "%.3f, recall %.3f (%d/%d), max error %.4f m %.3f deg (mean %.2f mm), %d ambiguous "
      "rejected | per "
      "keyframe: descriptor %.3f, candidates %.3f, ranking %.3f, verification %.2f ms | per "
      "verified keyframe (%d): %.2f ms (prepare %.2f, correlative %.2f, coarse gicp %.2f, fine "
      "%.2f, overlap %.2f), %.1f candidate/seed pairs\n",
      d.method.c_str(), d.coarse.c_str(), d.keyframes, d.revisits, d.accepted, d.correct,
      d.precision, d.recall, d.found, d.revisits, d.max_error_m, d.max_error_deg,
      1000.0 * d.sum_error_m / std::max(1, d.correct), d.ambiguous, d.descriptor_ms,
      d.candidates_ms, d.ranking_ms, d.verification_ms, d.verified_queries,
      d.verification_ms_per_query, d.prepare_ms_per_query, d.correlative_ms_per_query,
      d.coarse_ms_per_query, d.fine_ms_per_query, d.overlap_ms_per_query,
      d.registrations_per_query);
}

void printDriveJson(const DriveResult& d) {
  std::printf(
      "{\"method\":\"%s\",\"coarse\":\"%s\",\"ambiguous\":%d,\"keyframes\":%d,\"revisits\":%d,"
      "\"accepted\":%d,\"correct\":%d,"
      "\"found\":%d,\"precision\":%.4f,\"recall\":%.4f,\"max_error_m\":%.5f,"
      "\"max_error_deg\":%.4f,\"descriptor_ms\":%.4f,\"candidates_ms\":%.4f,\"ranking_ms\":%.4f,"
      "\"verification_ms_per_keyframe\":%.3f,\"verification_ms_per_verified_keyframe\":%.3f,"
      "\"coarse_ms_per_verified_keyframe\":%.3f,\"fine_ms_per_verified_keyframe\":%.3f,"
      "\"overlap_ms_per_verified_keyframe\":%.3f,"
      "\"registrations_per_verified_keyframe\":%.2f,\"verified_keyframes\":%d}",
      d.method.c_str(), d.coarse.c_str(), d.ambiguous, d.keyframes, d.revisits, d.accepted,
      d.correct, d.found, d.precision, d.recall, d.max_error_m, d.max_error_deg, d.descriptor_ms,
      d.candidates_ms, d.ranking_ms, d.verification_ms, d.verification_ms_per_query,
      d.coarse_ms_per_query, d.fine_ms_per_query, d.overlap_ms_per_query, d.registrations_per_query,
      d.verified_queries);
}

struct CandidateOptions {
  std::vector<std::string> methods;  ///< loop_detection `method`s
  std::vector<std::string> worlds = {"forest:sparse", "forest:intermediate", "forest:dense",
                                     "city"};  ///< world[:forest density]
  std::vector<uint64_t> seeds = {1};
  double length = 500.0, spacing = 4.0;
};

/// Sum of per-drive results of one method (counts added, per-keyframe times weighted).
void accumulate(DriveResult& sum, const DriveResult& r) {
  sum.method = r.method;
  sum.coarse = r.coarse;
  const double w = r.keyframes;
  sum.keyframes += r.keyframes;
  sum.revisits += r.revisits;
  sum.found += r.found;
  sum.accepted += r.accepted;
  sum.correct += r.correct;
  sum.landmark_accepted += r.landmark_accepted;
  sum.max_error_m = std::max(sum.max_error_m, r.max_error_m);
  sum.max_error_deg = std::max(sum.max_error_deg, r.max_error_deg);
  sum.total_ms += r.total_ms * w;
  sum.landmark_ms += r.landmark_ms * w;
  sum.landmarks_mean += r.landmarks_mean * w;
}

void printCandidateLine(const std::string& what, const DriveResult& d) {
  std::printf(
      "%-26s %-20s kf %4d revisits %4d | accepted %4d (by hierarchy %4d) correct %4d | "
      "precision %.3f recall %.3f (%d/%d) | max error %.3f m %.2f deg | %.2f ms/kf (landmarks "
      "%.2f ms, %.1f per kf)\n",
      what.c_str(), d.coarse.c_str(), d.keyframes, d.revisits, d.accepted, d.landmark_accepted,
      d.correct, d.precision, d.recall, d.found, d.revisits, d.max_error_m, d.max_error_deg,
      d.total_ms, d.landmark_ms, d.landmarks_mean);
  std::fflush(stdout);
}

/// Every world x seed drive through every candidate method in lockstep; a summary per world.
int runCandidateComparison(const CandidateOptions& opt, bool explain) {
  std::vector<Variant> variants;
  for (const auto& m : opt.methods) {
    LoopDetectorParams p = g_params;
    p.method = m;
    variants.push_back({m, p});
  }
  std::printf(
      "# candidate sources: %.0f m routes, keyframes every %.1f m, revisit <= 5 m and >= "
      "%.0f m back, correct within 0.10 m / 0.5 deg\n",
      opt.length, opt.spacing, g_params.min_accum_distance_gap);
  for (const auto& world : opt.worlds) {
    std::vector<DriveResult> sums(variants.size());
    for (uint64_t seed : opt.seeds) {
      sim::LoopDriveParams dp;
      const size_t colon = world.find(':');
      dp.world = world.substr(0, colon);
      if (colon != std::string::npos) dp.forest_density = world.substr(colon + 1);
      dp.seed = seed;
      dp.length = opt.length;
      dp.spacing = opt.spacing;
      sim::LoopDrive sim_drive;
      std::string error;
      if (!sim::simulateLoopDrive(dp, sim_drive, &error)) {
        std::fprintf(stderr, "loop_benchmark: %s: %s\n", world.c_str(), error.c_str());
        return 1;
      }
      Drive drive{sim_drive.truth, sim_drive.keyframes};
      const auto results = benchmarkDrive(drive, variants, explain);
      for (size_t v = 0; v < results.size(); ++v) {
        printCandidateLine(world + " seed " + std::to_string(seed), results[v]);
        accumulate(sums[v], results[v]);
      }
    }
    for (auto& sum : sums) {
      const double kf = std::max(1, sum.keyframes);
      sum.total_ms /= kf;
      sum.landmark_ms /= kf;
      sum.landmarks_mean /= kf;
      sum.precision = sum.accepted ? double(sum.correct) / sum.accepted : 1.0;
      sum.recall = sum.revisits ? double(sum.found) / sum.revisits : 1.0;
      printCandidateLine(world + " (all seeds)", sum);
    }
  }
  return 0;
}

struct Options {
  bool json = false, explain = false;
  int queries = 20, reference_queries = 5;
  std::string method = "fast_gicp", reference = "pcl_gicp", baseline = "gicp";
  std::vector<int> sizes = {100, 1000, 5000};
  std::string overrides, baseline_overrides;  ///< --set / --baseline-set key=value as YAML
  CandidateOptions candidates;
};

/// key=value (nested keys with '/': group/key=value) appended to `yaml` as a YAML line.
std::string appendOverride(const std::string& kv, std::string& yaml) {
  const size_t eq = kv.find('=');
  if (eq == std::string::npos) return "expects key=value, got '" + kv + "'";
  const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
  const size_t slash = key.find('/');
  yaml += slash == std::string::npos
              ? key + ": " + value + "\n"
              : key.substr(0, slash) + ": {" + key.substr(slash + 1) + ": " + value + "}\n";
  return "";
}

void declareOptions(tools::CommandLine& cli, Options& o) {
  cli.flag("--json", "print the results as JSON", &o.json)
      .flag("--explain", "print why each query was accepted or rejected", &o.explain)
      .option("--queries", "N", "queries per database size (at least 1)", &o.queries)
      .option("--reference-queries", "N", "queries the reference registration verifies",
              &o.reference_queries)
      .option("--sizes", "100,1000,5000", "database sizes in keyframes",
              [&o](const std::string& v) {
                o.sizes.clear();
                std::stringstream ss(v);
                std::string item;
                while (std::getline(ss, item, ','))
                  o.sizes.push_back(std::max(1, std::atoi(item.c_str())));
                return std::string();
              })
      .option("--method", "fast_gicp|fast_vgicp|pcl_gicp|pcl_ndt",
              "the verification's registration", &o.method)
      .option("--reference", "M|none", "the reference registration measured in the same run",
              &o.reference)
      .option("--baseline-coarse", "gicp|correlative|none",
              "the previous pipeline's coarse stage, measured in the same run", &o.baseline)
      .option("--set", "key=value",
              "override one loop_detection parameter (nested keys with '/'); repeatable",
              [&o](const std::string& kv) { return appendOverride(kv, o.overrides); })
      .option("--baseline-set", "key=value",
              "override one parameter of the baseline only; repeatable",
              [&o](const std::string& kv) { return appendOverride(kv, o.baseline_overrides); })
      .option("--candidates", "scan_context,geometric_hierarchy,combined",
              "compare these candidate sources on simulated drives (only this part runs then)",
              [&o](const std::string& v) {
                o.candidates.methods = tools::splitCommaList(v);
                return std::string();
              })
      .option("--worlds", "forest:sparse,forest:intermediate,forest:dense,city",
              "--candidates: the worlds (world[:forest density])",
              [&o](const std::string& v) {
                o.candidates.worlds = tools::splitCommaList(v);
                return std::string();
              })
      .option("--seeds", "1,2,3", "--candidates: the worlds' seeds (default: 1)",
              [&o](const std::string& v) {
                o.candidates.seeds.clear();
                for (const auto& seed : tools::splitCommaList(v)) {
                  long long n = 0;
                  if (!tools::parseInt(seed, &n) || n < 0) return "'" + seed + "' is not a seed";
                  o.candidates.seeds.push_back(static_cast<uint64_t>(n));
                }
                return std::string();
              })
      .option("--length", "M", "--candidates: drive length", &o.candidates.length)
      .option("--spacing", "M", "--candidates: keyframe spacing", &o.candidates.spacing);
}

/// The configured pipeline and the baseline to measure against it; an exit status when a
/// registration, coarse method or override is not known.
std::optional<int> makeVariants(const tools::CommandLine& cli, Options& opt,
                                std::vector<Variant>& variants) {
  std::string& baseline = opt.baseline;
  variants.push_back({g_params.coarse_method, paramsFor(opt.method, g_params.coarse_method)});
  const std::string coarse = g_params.coarse_method;
  if (baseline == coarse && opt.baseline_overrides.empty()) baseline = "none";
  try {
    for (const auto& m : {opt.method, opt.reference}) {
      if (m != "none") createRegistration(RegistrationParams{m});
    }
    if (baseline != "none") {
      LoopDetectorParams b = paramsFor(opt.method, baseline);
      if (!opt.baseline_overrides.empty())
        readParams(YamlParamReader::fromString(opt.baseline_overrides), b);
      variants.push_back({opt.baseline_overrides.empty() ? baseline : "baseline", b});
    }
    for (const auto& v : variants) LoopDetector check(v.params);
  } catch (const std::exception& e) {
    return cli.fail(e.what());
  }
  return std::nullopt;
}

/// Pool of ray-cast scans around the town (downsampled once like stored keyframes) and the
/// same places re-scanned at the revisit offset with other noise.
SizeWorkload makeSizeWorkload() {
  const SyntheticWorld world = makeLoopTown(200.0, 120.0, 14.0, 7);
  const auto places = loopTownRoute(200.0, 120.0, 0.0, 5.0, 0.0, 0.0);
  SizeWorkload w;
  for (size_t i = 0; i < places.size(); ++i) {
    const Eigen::Isometry3d at =
        isometryFromPlanar(Pose2(places[i].x(), places[i].y(), places[i].z()));
    const Eigen::Isometry3d again = at * kRevisitOffset;
    w.pool_poses.push_back(at);
    w.pool.push_back(
        downsampleForLoop(*simulateSyntheticScan(world, places[i].head<2>(), places[i].z(),
                                                 SyntheticLidarParams(), 1),
                          0.4));
    const double yaw = std::atan2(again.linear()(1, 0), again.linear()(0, 0));
    w.revisit_clouds.push_back(simulateSyntheticScan(world, again.translation().head<2>(), yaw,
                                                     SyntheticLidarParams(), 1000 + i));
  }
  return w;
}

void printSize(const SizeResult& r, const Options& opt) {
  const std::string &method = opt.method, &reference = opt.reference;
  std::printf(
      "db %5d keyframes [%s, coarse %s]: insert %.3f ms | per query: descriptor %.3f, "
      "candidates %.3f (%.0f), ranking %.3f (%.1f), verification %.2f (%.1f pairs; prepare "
      "%.2f, correlative %.2f, coarse gicp %.2f, fine %.2f of which target %.2f (%.1f, "
      "%.1f iterations each), "
      "overlap %.2f), total %.2f ms, correct %d/%d (accepted %d; error mean %.1f max %.1f mm), "
      "%d ambiguous rejected | place recognition: tree %.3f ms, brute force %.3f ms, ratio %.1f",
      r.size, method.c_str(), r.coarse.c_str(), r.insert_ms, r.descriptor_ms, r.candidates_ms,
      r.phase1_mean, r.ranking_ms, r.phase2_mean, r.verification_ms, r.registrations_mean,
      r.prepare_ms, r.correlative_ms, r.coarse_ms, r.fine_ms, r.fine_target_ms,
      r.fine_registrations, r.fine_iterations / std::max(1e-9, r.fine_registrations), r.overlap_ms,
      r.total_ms, r.correct, r.queries, r.accepted, 1000.0 * r.sum_error_m / std::max(1, r.correct),
      1000.0 * r.max_error_m, r.ambiguous, r.tree_retrieval_ms, r.brute_retrieval_ms,
      r.brute_retrieval_ms / std::max(1e-9, r.tree_retrieval_ms));
  if (r.reference_verification_ms > 0) {
    std::printf(" | verification on %d queries: %s %.2f ms vs %s %.2f ms, ratio %.1fx",
                r.reference_queries, reference.c_str(), r.reference_verification_ms, method.c_str(),
                r.subset_verification_ms,
                r.reference_verification_ms / std::max(1e-9, r.subset_verification_ms));
  }
  std::printf("\n");
  std::fflush(stdout);
}

void printJson(const Options& opt, const std::vector<SizeResult>& results,
               const std::vector<DriveResult>& drives) {
  const std::string &method = opt.method, &reference = opt.reference;
  std::printf("{\"method\":\"%s\",\"reference\":\"%s\",\"database\":[", method.c_str(),
              reference.c_str());
  for (size_t i = 0; i < results.size(); ++i) {
    const auto& r = results[i];
    std::printf(
        "%s{\"keyframes\":%d,\"coarse\":\"%s\",\"ambiguous\":%d,\"prepare_ms\":%.4f,"
        "\"correlative_ms\":%.4f,\"coarse_gicp_ms\":%.4f,\"fine_ms\":%.4f,"
        "\"fine_target_ms\":%.4f,\"overlap_ms\":%.4f,\"insert_ms\":%.4f,\"descriptor_ms\":%.4f,"
        "\"candidates_ms\":%.4f,"
        "\"phase1_candidates\":%.1f,\"ranking_ms\":%.4f,\"phase2_candidates\":%.2f,"
        "\"registrations\":%.2f,\"verification_ms\":%.3f,\"total_ms\":%.3f,\"queries\":%d,"
        "\"accepted\":%d,\"correct\":%d,\"tree_retrieval_ms\":%.4f,"
        "\"brute_force_retrieval_ms\":%.4f,\"ratio_brute_over_tree\":%.2f,"
        "\"reference_queries\":%d,\"reference_verification_ms\":%.3f,"
        "\"subset_verification_ms\":%.3f,\"ratio_reference_over_method\":%.2f}",
        i ? "," : "", r.size, r.coarse.c_str(), r.ambiguous, r.prepare_ms, r.correlative_ms,
        r.coarse_ms, r.fine_ms, r.fine_target_ms, r.overlap_ms, r.insert_ms, r.descriptor_ms,
        r.candidates_ms, r.phase1_mean, r.ranking_ms, r.phase2_mean, r.registrations_mean,
        r.verification_ms, r.total_ms, r.queries, r.accepted, r.correct, r.tree_retrieval_ms,
        r.brute_retrieval_ms, r.brute_retrieval_ms / std::max(1e-9, r.tree_retrieval_ms),
        r.reference_queries, r.reference_verification_ms, r.subset_verification_ms,
        r.reference_verification_ms / std::max(1e-9, r.subset_verification_ms));
  }
  std::printf("],\"drive\":[");
  for (size_t i = 0; i < drives.size(); ++i) {
    if (i) std::printf(",");
    printDriveJson(drives[i]);
  }
  std::printf("]}\n");
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  tools::CommandLine cli(
      "loop_benchmark",
      "Loop detection: per-keyframe time of each phase against the database size and "
      "precision/recall on a simulated drive with revisits, with the configured pipeline and the "
      "previous one in the same run; or (--candidates) the candidate sources on simulated drives.");
  declareOptions(cli, opt);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  opt.queries = std::max(1, opt.queries);
  opt.reference_queries = std::max(0, opt.reference_queries);
  if (!opt.overrides.empty()) {
    const YamlParamReader yaml = YamlParamReader::fromString(opt.overrides);
    if (!yaml.ok()) return cli.fail("--set: " + yaml.error());
    readParams(yaml, g_params);
  }
  if (!opt.candidates.methods.empty()) {
    try {
      for (const auto& m : opt.candidates.methods) {
        LoopDetectorParams p = g_params;
        p.method = m;
        LoopDetector check(p);
      }
    } catch (const std::exception& e) {
      return cli.fail(e.what());
    }
    return runCandidateComparison(opt.candidates, opt.explain);
  }
  std::vector<Variant> variants;
  if (const auto exit_code = makeVariants(cli, opt, variants)) return *exit_code;
  const bool json = opt.json, explain = opt.explain;
  const std::string &method = opt.method, &reference = opt.reference;
  const SizeWorkload w = makeSizeWorkload();
  std::vector<SizeResult> results;
  for (int size : opt.sizes) {
    const auto measured =
        benchmarkSize(size, opt.queries, opt.reference_queries, w, variants, reference, explain);
    for (const auto& r : measured) {
      results.push_back(r);
      if (!json) printSize(r, opt);
    }
    if (!json && measured.size() > 1) {
      std::printf("db %5d keyframes: total per query %s / %s = %.2fx (same run, interleaved)\n",
                  size, measured[1].coarse.c_str(), measured[0].coarse.c_str(),
                  measured[1].total_ms / std::max(1e-9, measured[0].total_ms));
    }
  }
  const Drive drive = makeDrive();
  std::vector<DriveResult> drives = benchmarkDrive(drive, variants, explain);
  if (!json) {
    for (const auto& r : drives) printDrive(r);
    if (drives.size() > 1) {
      std::printf("drive verification per verified keyframe: %s / %s = %.2fx (same run)\n",
                  drives[1].coarse.c_str(), drives[0].coarse.c_str(),
                  drives[1].verification_ms_per_query /
                      std::max(1e-9, drives[0].verification_ms_per_query));
    }
  }
  if (reference != "none") {
    Variant ref = variants.front();
    ref.params.registration.method = reference;
    drives.push_back(benchmarkDrive(drive, {ref}, explain).front());
    if (!json) {
      printDrive(drives.back());
      std::printf("drive verification per verified keyframe: %s / %s = %.1fx\n", reference.c_str(),
                  method.c_str(),
                  drives.back().verification_ms_per_query /
                      std::max(1e-9, drives[0].verification_ms_per_query));
    }
  }
  if (!json) return 0;
  printJson(opt, results, drives);
  return 0;
}
