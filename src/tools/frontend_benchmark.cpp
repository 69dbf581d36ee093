// frontend_benchmark: the keyframe tracker's guess and recovery variants on the same prefiltered
// scans, in the same run: matched / failed / re-anchored scans, tracking and pre-tracker
// milliseconds per scan and the ratio against the constant-velocity tracker without recovery
// (the reference). --stride K keeps every K-th scan (a drive with dropped scans, K-1 in a row).
//
//   frontend_benchmark --scans DIR [--stride K] [--max-scans N] [--rate HZ] [--repeat R] [--json]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

struct Variant {
  std::string name;
  KeyframeTrackerParams params;
};

struct Outcome {
  size_t scans = 0, matched = 0, failed = 0, reanchored = 0, retried = 0;
  double tracking_ms = 0.0, pre_tracker_ms = 0.0;  ///< per scan, median over repeats
  Eigen::Isometry3d last_pose = Eigen::Isometry3d::Identity();
};

std::vector<Variant> variants() {
  KeyframeTrackerParams legacy;
  legacy.recovery = false;
  legacy.reanchor_after_failures = 0;
  KeyframeTrackerParams recovery;  // the defaults (imu: without IMU data, constant velocity)
  KeyframeTrackerParams pre = recovery;
  pre.guess = "pre_tracker";
  KeyframeTrackerParams light = pre;  // the cheap pre-tracker: half the points at each scale
  light.pre_tracker.coarse_voxel = 3.0;
  light.pre_tracker.fine_voxel = 1.5;
  light.pre_tracker.fine_max_correspondence = 2.0;
  return {{"constant_velocity (no recovery: reference)", legacy},
          {"default (no IMU here: constant velocity) + recovery", recovery},
          {"pre_tracker + recovery", pre},
          {"pre_tracker 3.0/1.5 m voxels + recovery", light}};
}

Outcome run(const Variant& v, const std::vector<std::pair<double, PointCloudConstPtr>>& scans) {
  KeyframeTracker tracker(v.params);
  Outcome o;
  for (const auto& [stamp, cloud] : scans) {
    const auto t0 = std::chrono::steady_clock::now();
    const TrackResult r = tracker.track(stamp, cloud);
    o.tracking_ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    o.pre_tracker_ms += r.pre_tracker_ms;
    ++o.scans;
    o.matched += r.status == TrackStatus::kMatched || r.status == TrackStatus::kFirstKeyframe;
    o.failed += r.status == TrackStatus::kMatchFailed;
    o.reanchored += r.reanchored;
    o.retried += r.attempts > 1;
    if (r.has_pose()) o.last_pose = r.pose;
  }
  o.tracking_ms /= std::max<size_t>(1, o.scans);
  o.pre_tracker_ms /= std::max<size_t>(1, o.scans);
  return o;
}

int usage(const std::string& why) {
  std::cerr << "frontend_benchmark: " << why << "\n"
            << "usage: frontend_benchmark --scans DIR [--stride K] [--max-scans N] [--rate HZ]\n"
               "       [--repeat R] [--json]\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  int stride = 1, repeat = 3;
  size_t max_scans = 0;
  double rate = 10.0;
  bool json = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--scans")
      dir = value();
    else if (a == "--stride")
      stride = std::max(1, std::atoi(value().c_str()));
    else if (a == "--max-scans")
      max_scans = std::strtoul(value().c_str(), nullptr, 10);
    else if (a == "--rate")
      rate = std::atof(value().c_str());
    else if (a == "--repeat")
      repeat = std::max(1, std::atoi(value().c_str()));
    else if (a == "--json")
      json = true;
    else
      return usage("unexpected argument '" + a + "'");
  }
  if (dir.empty()) return usage("--scans DIR is required (a folder of KITTI .bin scans)");
  const std::vector<std::string> files = listFiles(dir, ".bin");
  if (files.empty()) return usage("no .bin scans in '" + dir + "'");

  // Prefilter once; every variant tracks the same clouds.
  CloudPrefilter prefilter;
  std::vector<std::pair<double, PointCloudConstPtr>> scans;
  for (size_t i = 0; i < files.size() && (max_scans == 0 || scans.size() < max_scans);
       i += stride) {
    PointCloud raw;
    std::string error;
    if (!readKittiBin(files[i], raw, &error)) {
      std::cerr << "frontend_benchmark: " << error << " (skipped)\n";
      continue;
    }
    const CloudPrefilterResult f = prefilter.filter(raw);
    if (f.ok) scans.emplace_back(double(i) / rate, f.cloud);
  }

  const std::vector<Variant> vs = variants();
  std::vector<Outcome> best(vs.size());
  for (int r = 0; r < repeat; ++r)  // interleaved, so load changes hit every variant alike
    for (size_t v = 0; v < vs.size(); ++v) {
      Outcome o = run(vs[v], scans);
      if (r == 0 || o.tracking_ms < best[v].tracking_ms) best[v] = o;  // least disturbed run
    }

  nlohmann::json doc = {
      {"scans", scans.size()}, {"stride", stride}, {"variants", nlohmann::json::array()}};
  if (!json)
    std::printf(
        "%zu scans of %s, every %d-th, best of %d runs\n%-44s %7s %6s %6s %7s %9s %9s %7s %10s\n",
        scans.size(), dir.c_str(), stride, repeat, "variant", "matched", "failed", "reanch",
        "retried", "track_ms", "pre_ms", "ratio", "end_diff_m");
  for (size_t v = 0; v < vs.size(); ++v) {
    const Outcome& o = best[v];
    const double ratio = o.tracking_ms / std::max(1e-9, best[0].tracking_ms);
    const double diff = (best[0].last_pose.translation() - o.last_pose.translation()).norm();
    doc["variants"].push_back({{"name", vs[v].name},
                               {"matched", o.matched},
                               {"failed", o.failed},
                               {"reanchored", o.reanchored},
                               {"retried", o.retried},
                               {"tracking_ms_per_scan", o.tracking_ms},
                               {"pre_tracker_ms_per_scan", o.pre_tracker_ms},
                               {"ratio_vs_reference", ratio},
                               {"end_difference_m", diff}});
    if (!json)
      std::printf("%-44s %7zu %6zu %6zu %7zu %9.2f %9.2f %7.2f %10.3f\n", vs[v].name.c_str(),
                  o.matched, o.failed, o.reanchored, o.retried, o.tracking_ms, o.pre_tracker_ms,
                  ratio, diff);
  }
  if (json) std::cout << doc.dump(2) << "\n";
  return 0;
}
