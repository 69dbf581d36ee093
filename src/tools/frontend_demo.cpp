// Offline LiDAR front-end over real scans: prefilter + scan-to-keyframe tracker on the six
// patchwork scans and the KITTI 00 pair of ../shared/data (or any folder of KITTI .bin scans).
// Prints per-scan pose, fitness, iterations and milliseconds per stage.
//   (the options: frontend_demo --help)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/odometry/keyframe_tracker.h"
#include "support/command_line.h"

using namespace osm_graph_slam;
namespace fs = std::filesystem;

namespace {

std::string defaultDataDir() {
  if (const char* env = std::getenv("OGS_SHARED_DATA_DIR")) return env;
  std::error_code ec;
  const auto exe = fs::canonical("/proc/self/exe", ec);
  if (!ec) {
    const auto candidate = exe.parent_path() / "../../../../../shared/data";
    if (fs::exists(candidate)) return fs::canonical(candidate).string();
  }
  return "../shared/data";
}

double ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since)
      .count();
}

/// Runs prefilter + tracker over one sequence of scans; returns false if nothing could be read.
bool runSequence(const fs::path& dir, const KeyframeTrackerParams& params, double rate_hz) {
  const auto files = listFiles(dir.string(), ".bin");
  if (files.empty()) {
    std::cerr << "[demo] no .bin scans in " << dir << "\n";
    return false;
  }
  std::printf("\n== %s: %zu scans, registration %s ==\n", dir.string().c_str(), files.size(),
              params.registration.method.c_str());
  std::printf("%4s %-12s %7s %6s %8s %8s %8s %8s %5s %8s %8s %s\n", "scan", "status", "points",
              "kf", "x", "y", "z", "yaw_deg", "iter", "fitness", "pf_ms", "reg_ms");
  CloudPrefilter prefilter;
  KeyframeTracker tracker(params);
  double pf_total = 0, reg_total = 0;
  int matched = 0;
  for (size_t i = 0; i < files.size(); ++i) {
    PointCloud raw;
    std::string error;
    if (!readKittiBin(files[i], raw, &error)) {
      std::printf("%4zu skipped: %s\n", i, error.c_str());
      continue;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const auto filtered = prefilter.filter(raw);
    const double pf_ms = ms(t0);
    pf_total += pf_ms;
    if (!filtered.ok) {
      std::printf("%4zu prefilter left nothing: %s\n", i, filtered.reason.c_str());
      continue;
    }
    const auto t1 = std::chrono::steady_clock::now();
    const TrackResult r = tracker.track(static_cast<double>(i) / rate_hz, filtered.cloud);
    const double reg_ms = ms(t1);
    reg_total += reg_ms;
    if (r.status == TrackStatus::kMatched) ++matched;
    const Eigen::Vector3d t = r.pose.translation();
    const double yaw = std::atan2(r.pose.linear()(1, 0), r.pose.linear()(0, 0)) * 180.0 / M_PI;
    std::printf("%4zu %-12s %7zu %5llu%s %8.3f %8.3f %8.3f %8.3f %5d %8.4f %8.1f %8.1f %s\n", i,
                toString(r.status), filtered.cloud->size(),
                static_cast<unsigned long long>(r.keyframe_id), r.new_keyframe ? "*" : " ", t.x(),
                t.y(), t.z(), yaw, r.registration.iterations,
                std::isfinite(r.registration.fitness) ? r.registration.fitness : 0.0, pf_ms, reg_ms,
                r.message.c_str());
  }
  const double n = static_cast<double>(files.size());
  std::printf(
      "keyframes %llu, matched %d/%zu, mean prefilter %.1f ms, mean tracking %.1f ms, "
      "%.1f scans/s (* = new keyframe)\n",
      static_cast<unsigned long long>(tracker.keyframeCount()), matched, files.size() - 1,
      pf_total / n, reg_total / n, 1000.0 * n / (pf_total + reg_total));
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = defaultDataDir();
  std::vector<std::string> scan_dirs;
  KeyframeTrackerParams params;
  double rate_hz = 10.0;
  tools::CommandLine cli("frontend_demo",
                         "Offline LiDAR front-end over real scans: prefilter + scan-to-keyframe "
                         "tracker; prints per-scan pose, fitness, iterations and milliseconds per "
                         "stage.");
  cli.option("--data", "DIR", "the shared data folder (its patchwork/ and kitti00/ scans)", &data)
      .option("--scans", "DIR", "a folder of KITTI .bin scans instead; repeatable",
              [&scan_dirs](const std::string& dir) {
                scan_dirs.push_back(dir);
                return std::string();
              })
      .option("--method", "fast_gicp|pcl_gicp|pcl_ndt", "the registration",
              &params.registration.method)
      .option("--rate", "HZ", "the scan rate the stamps are made with", &rate_hz);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (scan_dirs.empty()) {
    scan_dirs = {data + "/patchwork", data + "/kitti00"};
  }
  try {
    int done = 0;
    for (const auto& dir : scan_dirs) done += runSequence(dir, params, rate_hz) ? 1 : 0;
    if (done == 0) {
      std::cerr << "[demo] found no scans. The demo needs the real data of ../shared/data "
                   "(patchwork/000000.bin..000005.bin and kitti00/000094.bin, 000095.bin; see "
                   "its README.md), or --scans DIR with KITTI .bin files.\n";
      return 1;
    }
  } catch (const std::exception& e) {
    std::cerr << "[demo] " << e.what() << "\n";
    return 1;
  }
  return 0;
}
