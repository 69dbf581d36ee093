// Benchmarks the front-end on the real KITTI 00 pair 94 -> 95 in one process: the prefilter
// (and its octant-parallel outlier removal against the whole-cloud version), our fast_gicp,
// pcl::GeneralizedIterativeClosestPoint and pcl::NormalDistributionsTransform. Prints medians of
// several runs, errors against ground truth and ratios measured in the same run.
//   (the options: registration_benchmark --help)
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/registration/registration.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

namespace {

using Clock = std::chrono::steady_clock;

/// ../shared/data beside the checkout: $OGS_SHARED_DATA_DIR, else found from the executable
/// (<checkout>/build_ws/devel/lib/osm_graph_slam/<tool>), else relative to the working directory.
std::string defaultDataDir() {
  if (const char* env = std::getenv("OGS_SHARED_DATA_DIR")) return env;
  std::error_code ec;
  const auto exe = std::filesystem::canonical("/proc/self/exe", ec);
  if (!ec) {
    const auto candidate = exe.parent_path() / "../../../../../shared/data";
    if (std::filesystem::exists(candidate)) return std::filesystem::canonical(candidate).string();
  }
  return "../shared/data";
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

double timeMs(const std::function<void()>& fn) {
  const auto start = Clock::now();
  fn();
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

bool readTruth(const std::string& path, Eigen::Isometry3d* truth) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    int a, b;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    row >> a >> b;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) row >> m(r, c);
    if (!row) return false;
    truth->matrix() = m;
    return true;
  }
  return false;
}

struct MethodStats {
  std::string name;
  double set_target_ms = 0, align_ms = 0, total_ms = 0;
  double trans_err_cm = 0, rot_err_deg = 0, fitness = 0;
  int iterations = 0;
  bool converged = false;
  std::string message;
};

int g_k_correspondences = RegistrationParams().k_correspondences;
double g_epsilon = RegistrationParams().transformation_epsilon;

MethodStats runMethod(const std::string& method, int runs, int threads, const PointCloudPtr& target,
                      const PointCloudPtr& source, const Eigen::Isometry3d& truth) {
  MethodStats stats;
  stats.name = method;
  RegistrationParams params;
  params.method = method;
  params.num_threads = threads;
  params.k_correspondences = g_k_correspondences;
  params.transformation_epsilon = g_epsilon;
  std::vector<double> set_ms, align_ms, total_ms;
  RegistrationResult result;
  for (int i = 0; i < runs; ++i) {
    auto reg = createRegistration(params);
    const double st = timeMs([&] { reg->setTarget(target); });
    const double al = timeMs([&] { result = reg->align(source, Eigen::Isometry3d::Identity()); });
    set_ms.push_back(st);
    align_ms.push_back(al);
    total_ms.push_back(st + al);
  }
  stats.set_target_ms = median(set_ms);
  stats.align_ms = median(align_ms);
  stats.total_ms = median(total_ms);
  stats.converged = result.converged;
  stats.message = result.message;
  stats.iterations = result.iterations;
  stats.fitness = result.fitness;
  const Eigen::Isometry3d err = truth.inverse() * result.transform;
  stats.trans_err_cm = err.translation().norm() * 100.0;
  stats.rot_err_deg = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
  return stats;
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = defaultDataDir() + "/kitti00";
  int runs = 5;
  int threads = 0;
  bool json = false;
  double voxel = CloudPrefilterParams().voxel_leaf_size;
  tools::CommandLine cli("registration_benchmark",
                         "The front-end on the real KITTI 00 pair 94 -> 95 in one process: the "
                         "prefilter, our fast_gicp, PCL's GICP and NDT; medians of several runs, "
                         "errors against ground truth and ratios measured in the same run.");
  cli.option("--data", "DIR", "the folder of 000094.bin, 000095.bin and gt_relative_lidar.txt",
             &data)
      .option("--runs", "N", "runs per method; the median counts", &runs)
      .option("--threads", "N", "threads (0: the library's default)", &threads)
      .option("--k", "N", "GICP covariance neighbours", &g_k_correspondences)
      .option("--epsilon", "E", "GICP convergence epsilon", &g_epsilon)
      .option("--voxel", "M", "the prefilter's voxel size", &voxel)
      .flag("--json", "print the results as JSON", &json);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  runs = std::max(1, runs);
  PointCloudPtr raw_a = std::make_shared<PointCloud>(), raw_b = std::make_shared<PointCloud>();
  Eigen::Isometry3d truth;
  std::string error;
  if (!readKittiBin(data + "/000094.bin", *raw_a, &error) ||
      !readKittiBin(data + "/000095.bin", *raw_b, &error) ||
      !readTruth(data + "/gt_relative_lidar.txt", &truth)) {
    std::cerr << "registration_benchmark: needs " << data
              << "/{000094.bin,000095.bin,gt_relative_lidar.txt} (KITTI 00, see "
                 "../shared/data/README.md): "
              << (error.empty() ? "ground truth unreadable" : error) << "\n";
    return 1;
  }

  // Prefilter: full pipeline, and outlier removal alone (whole cloud vs octants).
  CloudPrefilterParams pf_params;
  pf_params.num_threads = threads;
  pf_params.voxel_leaf_size = voxel;
  CloudPrefilter prefilter(pf_params);
  std::vector<double> pf_ms;
  CloudPrefilterResult fa, fb;
  for (int i = 0; i < runs; ++i) {
    pf_ms.push_back(timeMs([&] { fa = prefilter.filter(*raw_a); }));
    fb = prefilter.filter(*raw_b);
  }
  CloudPrefilterParams no_outlier = pf_params;
  no_outlier.use_outlier_removal = false;
  const PointCloudPtr voxelized = CloudPrefilter(no_outlier).filter(*raw_a).cloud;
  CloudPrefilterParams no_voxel = no_outlier;
  no_voxel.use_voxel_grid = false;
  const PointCloudPtr cropped = CloudPrefilter(no_voxel).filter(*raw_a).cloud;
  auto octantBench = [&](const PointCloudPtr& cloud, double* whole, double* octants,
                         size_t* n_whole, size_t* n_oct) {
    std::vector<double> w, o;
    for (int i = 0; i < runs; ++i) {
      w.push_back(timeMs([&] { *n_whole = prefilter.removeOutliers(cloud, false)->size(); }));
      o.push_back(timeMs([&] { *n_oct = prefilter.removeOutliers(cloud, true)->size(); }));
    }
    *whole = median(w);
    *octants = median(o);
  };
  double vox_whole, vox_oct, full_whole, full_oct;
  size_t vox_nw, vox_no, full_nw, full_no;
  octantBench(voxelized, &vox_whole, &vox_oct, &vox_nw, &vox_no);
  octantBench(cropped, &full_whole, &full_oct, &full_nw, &full_no);

  std::vector<MethodStats> methods;
  for (const char* m : {"fast_gicp", "fast_vgicp", "pcl_gicp", "pcl_ndt"}) {
    methods.push_back(
        runMethod(m, std::string(m).rfind("fast", 0) == 0 ? runs : std::max(1, runs / 2 + 1),
                  threads, fa.cloud, fb.cloud, truth));
  }
  const double prefilter_ms = median(pf_ms);
  const MethodStats& ours = methods[0];
  const MethodStats& gicp = methods[2];
  const double speed_ratio = gicp.total_ms / ours.total_ms;
  // Per scan the tracker prefilters once and aligns once (the keyframe's covariances are reused).
  const double scans_per_s = 1000.0 / (prefilter_ms + ours.align_ms);
  const unsigned hw = std::thread::hardware_concurrency();

  if (json) {
    std::ostringstream o;
    o.precision(6);
    o << "{\"data\":\"" << data << "\",\"runs\":" << runs << ",\"threads\":" << threads
      << ",\"hardware_threads\":" << hw << ",\"input_points\":" << raw_a->size()
      << ",\"filtered_points\":" << fa.cloud->size() << ",\"prefilter_ms\":" << prefilter_ms
      << ",\"outlier_voxelized\":{\"points\":" << voxelized->size() << ",\"whole_ms\":" << vox_whole
      << ",\"octants_ms\":" << vox_oct << ",\"speedup\":" << vox_whole / vox_oct
      << ",\"kept_whole\":" << vox_nw << ",\"kept_octants\":" << vox_no << "}"
      << ",\"outlier_full_resolution\":{\"points\":" << cropped->size()
      << ",\"whole_ms\":" << full_whole << ",\"octants_ms\":" << full_oct
      << ",\"speedup\":" << full_whole / full_oct << ",\"kept_whole\":" << full_nw
      << ",\"kept_octants\":" << full_no << "},\"methods\":[";
    for (size_t i = 0; i < methods.size(); ++i) {
      const auto& m = methods[i];
      o << (i ? "," : "") << "{\"name\":\"" << m.name
        << "\",\"converged\":" << (m.converged ? "true" : "false")
        << ",\"set_target_ms\":" << m.set_target_ms << ",\"align_ms\":" << m.align_ms
        << ",\"total_ms\":" << m.total_ms << ",\"iterations\":" << m.iterations
        << ",\"fitness\":" << m.fitness << ",\"translation_error_cm\":" << m.trans_err_cm
        << ",\"rotation_error_deg\":" << m.rot_err_deg
        << ",\"speed_ratio_vs_pcl_gicp\":" << gicp.total_ms / m.total_ms << "}";
    }
    o << "],\"fast_gicp_speedup_vs_pcl_gicp\":" << speed_ratio
      << ",\"prefilter_plus_registration_scans_per_s\":" << scans_per_s << "}";
    std::cout << o.str() << std::endl;
    return 0;
  }
  std::printf("KITTI 00 94->95, %d runs (median), threads=%d (hardware %u)\n", runs, threads, hw);
  std::printf("prefilter: %zu -> %zu points, %.1f ms\n", raw_a->size(), fa.cloud->size(),
              prefilter_ms);
  std::printf(
      "outlier removal on voxelized cloud (%zu pts): whole %.1f ms, octants %.1f ms, "
      "speed-up %.2fx (kept %zu vs %zu)\n",
      voxelized->size(), vox_whole, vox_oct, vox_whole / vox_oct, vox_nw, vox_no);
  std::printf(
      "outlier removal on full-res cloud (%zu pts): whole %.1f ms, octants %.1f ms, "
      "speed-up %.2fx (kept %zu vs %zu)\n",
      cropped->size(), full_whole, full_oct, full_whole / full_oct, full_nw, full_no);
  std::printf("%-10s %9s %9s %9s %5s %9s %9s %9s %s\n", "method", "target_ms", "align_ms",
              "total_ms", "iter", "fitness", "err_cm", "err_deg", "x_vs_pcl_gicp");
  for (const auto& m : methods) {
    std::printf("%-10s %9.1f %9.1f %9.1f %5d %9.4f %9.2f %9.4f %.2f%s\n", m.name.c_str(),
                m.set_target_ms, m.align_ms, m.total_ms, m.iterations, m.fitness, m.trans_err_cm,
                m.rot_err_deg, gicp.total_ms / m.total_ms,
                m.converged ? "" : (" NOT CONVERGED: " + m.message).c_str());
  }
  std::printf("fast_gicp is %.2fx faster than pcl_gicp; prefilter + registration: %.1f scans/s\n",
              speed_ratio, scans_per_s);
  return 0;
}
