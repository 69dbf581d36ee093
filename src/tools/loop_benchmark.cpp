// Loop detection benchmark.
//  1. Per-keyframe time of each phase with 100, 1,000 and 5,000 keyframes in the database
//     (keyframes laid on a lawnmower drive over a 1 km^2 area, scans from a pool of ray-cast
//     town scans), plus the reference measured in the same run: brute-force Scan Context search
//     over the whole database vs the ring-key KD-tree retrieval.
//  2. Precision/recall and per-phase time on a simulated drive with revisits (ray-cast town
//     with a repetitive facade street, drifting odometry).
// Usage: loop_benchmark [--json] [--queries N] [--reference-queries N] [--sizes 100,1000,5000]
//                       [--method fast_gicp] [--reference pcl_gicp|none]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/loop/synthetic_world.h"

using namespace osm_graph_slam;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

struct SizeResult {
  int size = 0;
  double insert_ms = 0, descriptor_ms = 0, candidates_ms = 0, ranking_ms = 0, verification_ms = 0,
         total_ms = 0;
  double tree_retrieval_ms = 0, brute_retrieval_ms = 0;
  double phase1_mean = 0, phase2_mean = 0, registrations_mean = 0;
  int accepted = 0, correct = 0, queries = 0;
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
                                            const std::string& method, double* insert_ms) {
  LoopDetectorParams params;
  params.registration.method = method;
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
bool correctLoop(const DetectedLoop& loop, int target, const SizeWorkload& w) {
  const size_t n = w.pool_poses.size();
  const Eigen::Isometry3d truth =
      w.pool_poses[loop.to_id % n].inverse() * w.pool_poses[target % n] * kRevisitOffset;
  const Eigen::Isometry3d err = truth.inverse() * loop.relative_pose;
  return err.translation().norm() <= 0.1 &&
         Eigen::AngleAxisd(err.linear()).angle() <= 0.5 * M_PI / 180.0;
}

SizeResult benchmarkSize(int size, int queries, int reference_queries, const SizeWorkload& w,
                         const std::string& method, const std::string& reference) {
  SizeResult out;
  out.size = size;
  out.queries = queries;
  auto detector = buildDatabase(size, w, method, &out.insert_ms);
  const LoopDetectorParams& params = detector->params();
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> pick(0, size - 1);
  std::vector<int> targets;
  for (int q = 0; q < queries; ++q) targets.push_back(pick(rng));
  for (int q = 0; q < queries; ++q) {
    const LoopKeyframe kf = revisitQuery(size, q, targets[q], w);
    const auto loop = detector->detect(kf);
    const LoopQueryStats& s = detector->lastStats();
    out.descriptor_ms += s.descriptor_ms;
    out.candidates_ms += s.candidates_ms;
    out.ranking_ms += s.ranking_ms;
    out.verification_ms += s.verification_ms;
    if (q < reference_queries) out.subset_verification_ms += s.verification_ms;
    out.phase1_mean += s.phase1_candidates;
    out.phase2_mean += s.phase2_candidates;
    out.registrations_mean += s.verified;
    if (loop) {
      ++out.accepted;
      out.correct += correctLoop(*loop, targets[q], w);
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
  for (double* v : {&out.descriptor_ms, &out.candidates_ms, &out.ranking_ms, &out.verification_ms,
                    &out.phase1_mean, &out.phase2_mean, &out.registrations_mean,
                    &out.tree_retrieval_ms, &out.brute_retrieval_ms}) {
    *v /= queries;
  }
  out.total_ms = out.descriptor_ms + out.candidates_ms + out.ranking_ms + out.verification_ms;
  out.reference_queries = std::min(reference_queries, queries);
  if (reference != "none" && out.reference_queries > 0) {
    detector.reset();
    auto ref = buildDatabase(size, w, reference, nullptr);
    for (int q = 0; q < out.reference_queries; ++q) {
      ref->detect(revisitQuery(size, q, targets[q], w));
      out.reference_verification_ms += ref->lastStats().verification_ms;
    }
    out.reference_verification_ms /= out.reference_queries;
    out.subset_verification_ms /= out.reference_queries;
  }
  return out;
}

struct DriveResult {
  std::string method;
  int keyframes = 0, revisits = 0, found = 0, accepted = 0, correct = 0;
  double precision = 0, recall = 0, max_error_m = 0, max_error_deg = 0;
  double descriptor_ms = 0, candidates_ms = 0, ranking_ms = 0, verification_ms = 0;
  double verification_ms_per_query = 0, registrations_per_query = 0;
  double coarse_ms_per_query = 0, fine_ms_per_query = 0, overlap_ms_per_query = 0;
  int verified_queries = 0;
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

DriveResult benchmarkDrive(const Drive& d, const std::string& method) {
  DriveResult out;
  out.method = method;
  LoopDetectorParams params;
  params.registration.method = method;
  LoopDetector detector(params, [](LogLevel, const std::string&) {});
  for (size_t i = 0; i < d.keyframes.size(); ++i) {
    const double s = d.keyframes[i].accum_distance;
    const auto loop = detector.process(d.keyframes[i]);
    const auto& st = detector.lastStats();
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
      ++out.verified_queries;
    }
    bool revisit = false;
    for (size_t j = 0; j < i && s - d.keyframes[j].accum_distance >= params.min_accum_distance_gap;
         ++j) {
      if ((d.truth[i].translation() - d.truth[j].translation()).norm() <= 5.0) revisit = true;
    }
    out.revisits += revisit;
    if (loop) {
      ++out.accepted;
      const Eigen::Isometry3d err =
          (d.truth[loop->to_id].inverse() * d.truth[i]).inverse() * loop->relative_pose;
      const double et = err.translation().norm();
      const double er = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
      out.max_error_m = std::max(out.max_error_m, et);
      out.max_error_deg = std::max(out.max_error_deg, er);
      const bool correct = et <= 0.10 && er <= 0.5;
      out.correct += correct;
      out.found += revisit && correct;
    }
  }
  out.keyframes = static_cast<int>(d.keyframes.size());
  out.precision = out.accepted ? static_cast<double>(out.correct) / out.accepted : 1.0;
  out.recall = out.revisits ? static_cast<double>(out.found) / out.revisits : 1.0;
  for (double* v :
       {&out.descriptor_ms, &out.candidates_ms, &out.ranking_ms, &out.verification_ms}) {
    *v /= out.keyframes;
  }
  if (out.verified_queries) {
    for (double* v :
         {&out.verification_ms_per_query, &out.registrations_per_query, &out.coarse_ms_per_query,
          &out.fine_ms_per_query, &out.overlap_ms_per_query}) {
      *v /= out.verified_queries;
    }
  }
  return out;
}

void printDrive(const DriveResult& d) {
  std::printf(
      "drive [%s]: %d keyframes, %d revisits, %d accepted (%d correct), precision %.3f, recall "
      "%.3f (%d/%d), max error %.4f m %.3f deg | per keyframe: descriptor %.3f, candidates "
      "%.3f, ranking %.3f, verification %.2f ms | per verified keyframe (%d): %.2f ms (coarse "
      "%.2f, fine %.2f, overlap %.2f), %.1f candidate/seed pairs\n",
      d.method.c_str(), d.keyframes, d.revisits, d.accepted, d.correct, d.precision, d.recall,
      d.found, d.revisits, d.max_error_m, d.max_error_deg, d.descriptor_ms, d.candidates_ms,
      d.ranking_ms, d.verification_ms, d.verified_queries, d.verification_ms_per_query,
      d.coarse_ms_per_query, d.fine_ms_per_query, d.overlap_ms_per_query,
      d.registrations_per_query);
}

void printDriveJson(const DriveResult& d) {
  std::printf(
      "{\"method\":\"%s\",\"keyframes\":%d,\"revisits\":%d,\"accepted\":%d,\"correct\":%d,"
      "\"found\":%d,\"precision\":%.4f,\"recall\":%.4f,\"max_error_m\":%.5f,"
      "\"max_error_deg\":%.4f,\"descriptor_ms\":%.4f,\"candidates_ms\":%.4f,\"ranking_ms\":%.4f,"
      "\"verification_ms_per_keyframe\":%.3f,\"verification_ms_per_verified_keyframe\":%.3f,"
      "\"coarse_ms_per_verified_keyframe\":%.3f,\"fine_ms_per_verified_keyframe\":%.3f,"
      "\"overlap_ms_per_verified_keyframe\":%.3f,"
      "\"registrations_per_verified_keyframe\":%.2f,\"verified_keyframes\":%d}",
      d.method.c_str(), d.keyframes, d.revisits, d.accepted, d.correct, d.found, d.precision,
      d.recall, d.max_error_m, d.max_error_deg, d.descriptor_ms, d.candidates_ms, d.ranking_ms,
      d.verification_ms, d.verification_ms_per_query, d.coarse_ms_per_query, d.fine_ms_per_query,
      d.overlap_ms_per_query, d.registrations_per_query, d.verified_queries);
}

}  // namespace

int main(int argc, char** argv) {
  bool json = false;
  int queries = 20, reference_queries = 5;
  std::string method = "fast_gicp", reference = "pcl_gicp";
  std::vector<int> sizes = {100, 1000, 5000};
  const char* usage =
      "usage: loop_benchmark [--json] [--queries N] [--reference-queries N] [--sizes "
      "100,1000,5000] [--method fast_gicp|fast_vgicp|pcl_gicp|pcl_ndt] [--reference M|none]\n";
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--json")) {
      json = true;
    } else if (!std::strcmp(argv[i], "--queries") && has_value) {
      queries = std::max(1, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--reference-queries") && has_value) {
      reference_queries = std::max(0, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--method") && has_value) {
      method = argv[++i];
    } else if (!std::strcmp(argv[i], "--reference") && has_value) {
      reference = argv[++i];
    } else if (!std::strcmp(argv[i], "--sizes") && has_value) {
      sizes.clear();
      std::stringstream ss(argv[++i]);
      std::string item;
      while (std::getline(ss, item, ',')) sizes.push_back(std::max(1, std::atoi(item.c_str())));
    } else {
      std::cerr << usage;
      return 2;
    }
  }
  try {
    for (const auto& m : {method, reference}) {
      if (m != "none") createRegistration(RegistrationParams{m});
    }
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n" << usage;
    return 2;
  }
  // Pool of ray-cast scans around the town (downsampled once like stored keyframes) and the
  // same places re-scanned at the revisit offset with other noise.
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
  std::vector<SizeResult> results;
  for (int size : sizes) {
    results.push_back(benchmarkSize(size, queries, reference_queries, w, method, reference));
    const auto& r = results.back();
    if (!json) {
      std::printf(
          "db %5d keyframes [%s]: insert %.3f ms | per query: descriptor %.3f, candidates %.3f "
          "(%.0f), ranking %.3f (%.1f), verification %.2f (%.1f registrations), total %.2f ms, "
          "correct %d/%d (accepted %d) | place recognition: tree %.3f ms, brute force %.3f ms, "
          "ratio %.1f",
          r.size, method.c_str(), r.insert_ms, r.descriptor_ms, r.candidates_ms, r.phase1_mean,
          r.ranking_ms, r.phase2_mean, r.verification_ms, r.registrations_mean, r.total_ms,
          r.correct, r.queries, r.accepted, r.tree_retrieval_ms, r.brute_retrieval_ms,
          r.brute_retrieval_ms / std::max(1e-9, r.tree_retrieval_ms));
      if (r.reference_verification_ms > 0) {
        std::printf(" | verification on %d queries: %s %.2f ms vs %s %.2f ms, ratio %.1fx",
                    r.reference_queries, reference.c_str(), r.reference_verification_ms,
                    method.c_str(), r.subset_verification_ms,
                    r.reference_verification_ms / std::max(1e-9, r.subset_verification_ms));
      }
      std::printf("\n");
      std::fflush(stdout);
    }
  }
  const Drive drive = makeDrive();
  std::vector<DriveResult> drives = {benchmarkDrive(drive, method)};
  if (!json) printDrive(drives.back());
  if (reference != "none") {
    drives.push_back(benchmarkDrive(drive, reference));
    if (!json) {
      printDrive(drives.back());
      std::printf("drive verification per verified keyframe: %s / %s = %.1fx\n", reference.c_str(),
                  method.c_str(),
                  drives[1].verification_ms_per_query /
                      std::max(1e-9, drives[0].verification_ms_per_query));
    }
  }
  if (!json) return 0;
  std::printf("{\"method\":\"%s\",\"reference\":\"%s\",\"database\":[", method.c_str(),
              reference.c_str());
  for (size_t i = 0; i < results.size(); ++i) {
    const auto& r = results[i];
    std::printf(
        "%s{\"keyframes\":%d,\"insert_ms\":%.4f,\"descriptor_ms\":%.4f,\"candidates_ms\":%.4f,"
        "\"phase1_candidates\":%.1f,\"ranking_ms\":%.4f,\"phase2_candidates\":%.2f,"
        "\"registrations\":%.2f,\"verification_ms\":%.3f,\"total_ms\":%.3f,\"queries\":%d,"
        "\"accepted\":%d,\"correct\":%d,\"tree_retrieval_ms\":%.4f,"
        "\"brute_force_retrieval_ms\":%.4f,\"ratio_brute_over_tree\":%.2f,"
        "\"reference_queries\":%d,\"reference_verification_ms\":%.3f,"
        "\"subset_verification_ms\":%.3f,\"ratio_reference_over_method\":%.2f}",
        i ? "," : "", r.size, r.insert_ms, r.descriptor_ms, r.candidates_ms, r.phase1_mean,
        r.ranking_ms, r.phase2_mean, r.registrations_mean, r.verification_ms, r.total_ms, r.queries,
        r.accepted, r.correct, r.tree_retrieval_ms, r.brute_retrieval_ms,
        r.brute_retrieval_ms / std::max(1e-9, r.tree_retrieval_ms), r.reference_queries,
        r.reference_verification_ms, r.subset_verification_ms,
        r.reference_verification_ms / std::max(1e-9, r.subset_verification_ms));
  }
  std::printf("],\"drive\":[");
  for (size_t i = 0; i < drives.size(); ++i) {
    if (i) std::printf(",");
    printDriveJson(drives[i]);
  }
  std::printf("]}\n");
  return 0;
}
