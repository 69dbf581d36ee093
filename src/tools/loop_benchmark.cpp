// Loop detection benchmark.
//  1. Per-keyframe time of each phase with 100, 1,000 and 5,000 keyframes in the database
//     (keyframes laid on a lawnmower drive over a 1 km^2 area, scans from a pool of ray-cast
//     town scans), plus the reference measured in the same run: brute-force Scan Context search
//     over the whole database vs the ring-key KD-tree retrieval.
//  2. Precision/recall and per-phase time on a simulated drive with revisits (ray-cast town
//     with a repetitive facade street, drifting odometry).
// Usage: loop_benchmark [--json] [--queries N] [--sizes 100,1000,5000]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/loop/synthetic_world.h"

using namespace osm_graph_slam;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

Eigen::Isometry3d pose2d(double x, double y, double yaw) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() << x, y, 0.0;
  t.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).matrix();
  return t;
}

struct SizeResult {
  int size = 0;
  double insert_ms = 0, descriptor_ms = 0, candidates_ms = 0, ranking_ms = 0, verification_ms = 0,
         total_ms = 0;
  double tree_retrieval_ms = 0, brute_retrieval_ms = 0;
  double phase1_mean = 0, phase2_mean = 0;
};

SizeResult benchmarkSize(int size, int queries, const std::vector<PointCloudConstPtr>& pool) {
  LoopDetectorParams params;
  params.voxel_size = 0.0;  // pool clouds are already downsampled and shared
  params.coarse_max_correspondence_distance = 0.0;
  params.check_odometry_consistency = false;
  LoopDetector detector(params, [](LogLevel, const std::string&) {});
  // Lawnmower drive over 1000 m x 1000 m, keyframes every 2 m (lanes 20 m apart).
  SizeResult out;
  out.size = size;
  const double lane = 20.0, spacing = 2.0, width = 1000.0;
  const int per_lane = static_cast<int>(width / spacing);
  auto place = [&](int i) {
    const int l = i / per_lane, k = i % per_lane;
    const double x = (l % 2 == 0) ? k * spacing : width - k * spacing;
    return pose2d(x, l * lane, l % 2 == 0 ? 0.0 : M_PI);
  };
  auto start = Clock::now();
  for (int i = 0; i < size; ++i) {
    LoopKeyframe kf;
    kf.id = i;
    kf.odom_pose = place(i);
    kf.accum_distance = i * spacing;
    kf.cloud = pool[i % pool.size()];
    detector.addKeyframe(kf);
  }
  out.insert_ms = msSince(start) / size;
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> pick(0, size - 1);
  for (int q = 0; q < queries; ++q) {
    const int target = pick(rng);
    LoopKeyframe kf;
    kf.id = size + q;
    kf.odom_pose = place(target) * pose2d(1.0, 0.5, 0.2);
    kf.accum_distance = size * spacing + 100.0;
    kf.cloud = pool[target % pool.size()];
    detector.detect(kf);
    const LoopQueryStats& s = detector.lastStats();
    out.descriptor_ms += s.descriptor_ms;
    out.candidates_ms += s.candidates_ms;
    out.ranking_ms += s.ranking_ms;
    out.verification_ms += s.verification_ms;
    out.phase1_mean += s.phase1_candidates;
    out.phase2_mean += s.phase2_candidates;
    // Place-recognition retrieval: ring-key tree vs brute force over every keyframe.
    const ScanContext sc = computeScanContext(*kf.cloud, params.scan_context);
    start = Clock::now();
    const auto ranked = detector.rankCandidates(sc, detector.ringKeyCandidates(sc, size));
    out.tree_retrieval_ms += msSince(start);
    start = Clock::now();
    double best = 2.0;
    for (size_t i = 0; i < detector.size(); ++i) {
      best = std::min(
          best, matchScanContexts(sc, detector.entry(i).descriptor, params.scan_context).distance);
    }
    out.brute_retrieval_ms += msSince(start);
    if (best > 1.5 || ranked.size() > 1000) std::cerr << "unexpected\n";
  }
  for (double* v :
       {&out.descriptor_ms, &out.candidates_ms, &out.ranking_ms, &out.verification_ms,
        &out.phase1_mean, &out.phase2_mean, &out.tree_retrieval_ms, &out.brute_retrieval_ms}) {
    *v /= queries;
  }
  out.total_ms = out.descriptor_ms + out.candidates_ms + out.ranking_ms + out.verification_ms;
  return out;
}

struct DriveResult {
  int keyframes = 0, revisits = 0, found = 0, accepted = 0, correct = 0;
  double precision = 0, recall = 0, max_error_m = 0, max_error_deg = 0;
  double descriptor_ms = 0, candidates_ms = 0, ranking_ms = 0, verification_ms = 0;
  double verification_ms_per_query = 0;
  int verified_queries = 0;
};

DriveResult benchmarkDrive() {
  DriveResult out;
  const SyntheticWorld world = makeLoopTown(200.0, 120.0, 14.0, 7);
  auto route = loopTownRoute(200.0, 120.0, 0.0, 4.0, 0.0, 0.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  for (double x = 2.0; x <= 150.0; x += 4.0) route.emplace_back(x, 1.5, jitter(rng));
  LoopDetectorParams params;
  LoopDetector detector(params, [](LogLevel, const std::string&) {});
  std::vector<Eigen::Isometry3d> truth;
  std::vector<double> accum;
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  double s = 0.0;
  for (size_t i = 0; i < route.size(); ++i) {
    truth.push_back(pose2d(route[i].x(), route[i].y(), route[i].z()));
    if (i > 0) {
      Eigen::Isometry3d step = truth[i - 1].inverse() * truth[i];
      const double len = step.translation().norm();
      s += len;
      step.translation() *= 1.005;
      odom = odom * step * pose2d(0, 0, 0.0000524 * len);
    } else {
      odom = truth[0];
    }
    accum.push_back(s);
    LoopKeyframe kf;
    kf.id = i;
    kf.odom_pose = odom;
    kf.accum_distance = s;
    kf.cloud = simulateSyntheticScan(world, route[i].head<2>(), route[i].z(),
                                     SyntheticLidarParams(), 100 + i);
    const auto loop = detector.process(kf);
    const auto& st = detector.lastStats();
    out.descriptor_ms += st.descriptor_ms;
    out.candidates_ms += st.candidates_ms;
    out.ranking_ms += st.ranking_ms;
    out.verification_ms += st.verification_ms;
    if (st.verified > 0) {
      out.verification_ms_per_query += st.verification_ms;
      ++out.verified_queries;
    }
    bool revisit = false;
    for (size_t j = 0; j < i && s - accum[j] >= params.min_accum_distance_gap; ++j) {
      if ((truth[i].translation() - truth[j].translation()).norm() <= 5.0) revisit = true;
    }
    out.revisits += revisit;
    if (loop) {
      ++out.accepted;
      const Eigen::Isometry3d err =
          (truth[loop->to_id].inverse() * truth[i]).inverse() * loop->relative_pose;
      const double et = err.translation().norm();
      const double er = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
      out.max_error_m = std::max(out.max_error_m, et);
      out.max_error_deg = std::max(out.max_error_deg, er);
      const bool correct = et <= 0.10 && er <= 0.5;
      out.correct += correct;
      out.found += revisit && correct;
    }
  }
  out.keyframes = static_cast<int>(route.size());
  out.precision = out.accepted ? static_cast<double>(out.correct) / out.accepted : 1.0;
  out.recall = out.revisits ? static_cast<double>(out.found) / out.revisits : 1.0;
  for (double* v :
       {&out.descriptor_ms, &out.candidates_ms, &out.ranking_ms, &out.verification_ms}) {
    *v /= out.keyframes;
  }
  if (out.verified_queries) out.verification_ms_per_query /= out.verified_queries;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  bool json = false;
  int queries = 50;
  std::vector<int> sizes = {100, 1000, 5000};
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--json")) {
      json = true;
    } else if (!std::strcmp(argv[i], "--queries") && i + 1 < argc) {
      queries = std::max(1, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc) {
      sizes.clear();
      std::stringstream ss(argv[++i]);
      std::string item;
      while (std::getline(ss, item, ',')) sizes.push_back(std::max(1, std::stoi(item)));
    } else {
      std::cerr << "usage: loop_benchmark [--json] [--queries N] [--sizes 100,1000,5000]\n";
      return 2;
    }
  }
  // Pool of ray-cast scans around the town, downsampled once like stored keyframes.
  const SyntheticWorld world = makeLoopTown(200.0, 120.0, 14.0, 7);
  const auto places = loopTownRoute(200.0, 120.0, 0.0, 5.0, 0.0, 0.0);
  std::vector<PointCloudConstPtr> pool;
  for (const auto& p : places) {
    pool.push_back(downsampleForLoop(
        *simulateSyntheticScan(world, p.head<2>(), p.z(), SyntheticLidarParams(), 1), 0.4));
  }
  std::vector<SizeResult> results;
  for (int size : sizes) {
    results.push_back(benchmarkSize(size, queries, pool));
    const auto& r = results.back();
    if (!json) {
      std::printf(
          "db %5d keyframes: insert %.3f ms | per query: descriptor %.3f, candidates %.3f "
          "(%.0f), ranking %.3f (%.1f), verification %.2f, total %.2f ms | place recognition: "
          "tree %.3f ms, brute force %.3f ms, ratio brute/tree %.1f\n",
          r.size, r.insert_ms, r.descriptor_ms, r.candidates_ms, r.phase1_mean, r.ranking_ms,
          r.phase2_mean, r.verification_ms, r.total_ms, r.tree_retrieval_ms, r.brute_retrieval_ms,
          r.brute_retrieval_ms / std::max(1e-9, r.tree_retrieval_ms));
    }
  }
  const DriveResult d = benchmarkDrive();
  if (!json) {
    std::printf(
        "drive: %d keyframes, %d revisits, %d accepted (%d correct), precision %.3f, recall "
        "%.3f, max error %.4f m %.3f deg | per keyframe: descriptor %.3f, candidates %.3f, "
        "ranking %.3f, verification %.2f ms (%.1f ms per verified query, %d queries)\n",
        d.keyframes, d.revisits, d.accepted, d.correct, d.precision, d.recall, d.max_error_m,
        d.max_error_deg, d.descriptor_ms, d.candidates_ms, d.ranking_ms, d.verification_ms,
        d.verification_ms_per_query, d.verified_queries);
    return 0;
  }
  std::printf("{\"database\":[");
  for (size_t i = 0; i < results.size(); ++i) {
    const auto& r = results[i];
    std::printf(
        "%s{\"keyframes\":%d,\"insert_ms\":%.4f,\"descriptor_ms\":%.4f,\"candidates_ms\":%.4f,"
        "\"phase1_candidates\":%.1f,\"ranking_ms\":%.4f,\"phase2_candidates\":%.2f,"
        "\"verification_ms\":%.3f,\"total_ms\":%.3f,\"tree_retrieval_ms\":%.4f,"
        "\"brute_force_retrieval_ms\":%.4f,\"ratio_brute_over_tree\":%.2f}",
        i ? "," : "", r.size, r.insert_ms, r.descriptor_ms, r.candidates_ms, r.phase1_mean,
        r.ranking_ms, r.phase2_mean, r.verification_ms, r.total_ms, r.tree_retrieval_ms,
        r.brute_retrieval_ms, r.brute_retrieval_ms / std::max(1e-9, r.tree_retrieval_ms));
  }
  std::printf(
      "],\"drive\":{\"keyframes\":%d,\"revisits\":%d,\"accepted\":%d,\"correct\":%d,"
      "\"precision\":%.4f,\"recall\":%.4f,\"max_error_m\":%.5f,\"max_error_deg\":%.4f,"
      "\"descriptor_ms\":%.4f,\"candidates_ms\":%.4f,\"ranking_ms\":%.4f,"
      "\"verification_ms\":%.3f,\"verification_ms_per_verified_query\":%.2f}}\n",
      d.keyframes, d.revisits, d.accepted, d.correct, d.precision, d.recall, d.max_error_m,
      d.max_error_deg, d.descriptor_ms, d.candidates_ms, d.ranking_ms, d.verification_ms,
      d.verification_ms_per_query);
  return 0;
}
