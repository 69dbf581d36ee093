// stereo_odometry: the stereo visual odometry (visual/, D3VIL-SLAM's visual tracker, issue 56) on
// a folder of rectified stereo pairs in the KITTI odometry layout (image_l/ or image_0/, image_r/
// or image_1/, calib.txt, optionally poses.txt), 10 Hz. Prints the pairs tracked, the
// milliseconds per pair of each stage and, with poses.txt, the error against it: end drift (m
// and % of the path), worst position error, relative pose error per pair. --simulated N renders
// N pairs of the simulator's default drive instead (sim/stereo_camera_sim.h) and compares with
// their true poses.
//
//   stereo_odometry --sequence ../shared/data/kitti_stereo/sequence_1 --output vo_tum.txt
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/eval/trajectory_metrics.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/sim/simulator.h"
#include "osm_graph_slam/sim/stereo_camera_sim.h"
#include "osm_graph_slam/visual/stereo_odometry.h"
#include "support/command_line.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;
namespace fs = std::filesystem;

namespace {

/// The first of `names` that is a folder under `dir`.
fs::path imageFolder(const fs::path& dir, std::initializer_list<const char*> names) {
  for (const char* name : names)
    if (fs::is_directory(dir / name)) return dir / name;
  return {};
}

std::vector<fs::path> pngFiles(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".png") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

double median(const std::vector<double>& v) {
  return computeErrorStats(v).median;
}

double rotationDeg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}

/// End drift, worst position error and per-pair relative error against the ground truth.
void reportErrors(const Trajectory& estimate, const Trajectory& truth) {
  const size_t n = std::min(estimate.size(), truth.size());
  if (n < 2) return;
  double path = 0.0, worst = 0.0;
  std::vector<double> rpe_t, rpe_r;
  for (size_t i = 1; i < n; ++i) {
    path += (truth[i].pose.translation() - truth[i - 1].pose.translation()).norm();
    worst = std::max(worst, (estimate[i].pose.translation() - truth[i].pose.translation()).norm());
    const Eigen::Isometry3d de = estimate[i - 1].pose.inverse() * estimate[i].pose;
    const Eigen::Isometry3d dt = truth[i - 1].pose.inverse() * truth[i].pose;
    const Eigen::Isometry3d d = dt.inverse() * de;
    rpe_t.push_back(d.translation().norm());
    rpe_r.push_back(rotationDeg(d.linear()));
  }
  const Eigen::Isometry3d end = truth[n - 1].pose.inverse() * estimate[n - 1].pose;
  std::printf(
      "against the truth (%zu pairs, %.1f m): end drift %.3f m (%.2f %% of the path), %.3f deg; "
      "worst position error %.3f m; per pair: translation median %.3f m, worst %.3f m, rotation "
      "median %.3f deg, worst %.3f deg\n",
      n, path, end.translation().norm(), 100.0 * end.translation().norm() / std::max(path, 1e-9),
      rotationDeg(end.linear()), worst, median(rpe_t), computeErrorStats(rpe_t).max, median(rpe_r),
      *std::max_element(rpe_r.begin(), rpe_r.end()));
}

/// Where the pairs come from: a folder or the simulator.
struct PairSource {
  StereoCamera camera;
  size_t pairs = 0;
  std::function<bool(size_t, cv::Mat&, cv::Mat&)> read;  ///< pair i; false: missing
  Trajectory truth;  ///< left camera poses relative to the first (may be empty)
  std::string name;
};

std::optional<PairSource> folderSource(const fs::path& dir, std::string* error) {
  const fs::path left_dir = imageFolder(dir, {"image_l", "image_0"});
  const fs::path right_dir = imageFolder(dir, {"image_r", "image_1"});
  if (left_dir.empty() || right_dir.empty()) {
    *error = dir.string() + " has no image folders";
    return std::nullopt;
  }
  const std::optional<StereoCamera> camera =
      readKittiStereoCalibration((dir / "calib.txt").string(), error);
  if (!camera) return std::nullopt;
  PairSource source;
  source.camera = *camera;
  source.name = dir.string();
  const std::vector<fs::path> lefts = pngFiles(left_dir);
  source.pairs = lefts.size();
  source.read = [lefts, right_dir](size_t i, cv::Mat& left, cv::Mat& right) {
    left = cv::imread(lefts[i].string(), cv::IMREAD_GRAYSCALE);
    right = cv::imread((right_dir / lefts[i].filename()).string(), cv::IMREAD_GRAYSCALE);
    return !left.empty() && !right.empty() && left.size() == right.size();
  };
  if (fs::exists(dir / "poses.txt")) {
    const TrajectoryReadResult truth = readKittiPoses((dir / "poses.txt").string());
    if (truth.ok)
      source.truth = truth.trajectory;
    else
      std::cerr << "stereo_odometry: " << truth.error << "\n";
  }
  return source;
}

/// Pairs rendered every 0.1 s along the default simulated drive, from its LiDAR's pose.
std::optional<PairSource> simulatedSource(size_t pairs, std::string* error) {
  auto sim = std::make_shared<sim::UrbanSimulator>();
  if (!sim->build(sim::SimulationParams(), error)) return std::nullopt;
  const sim::StereoCameraModel model;
  PairSource source;
  source.camera = model.camera();
  source.pairs = std::min(pairs, sim->numScans());
  source.name = "the simulated drive";
  const Eigen::Isometry3d first = sim::kittiCameraFromLidar(sim->sensorPose(0.0));
  for (size_t i = 0; i < source.pairs; ++i) {
    const double t = sim->scanTime(i);
    source.truth.push_back({0.1 * static_cast<double>(i),
                            first.inverse() * sim::kittiCameraFromLidar(sim->sensorPose(t))});
  }
  source.read = [sim, model](size_t i, cv::Mat& left, cv::Mat& right) {
    const double t = sim->scanTime(i);
    sim::renderStereoPair(sim->scene().world, model, sim::kittiCameraFromLidar(sim->sensorPose(t)),
                          t, 1, left, right);
    return true;
  };
  return source;
}

}  // namespace

int main(int argc, char** argv) {
  std::string sequence, output;
  size_t max_frames = 1000000, simulated = 0;
  bool verbose = false;
  CommandLine cli("stereo_odometry",
                  "Stereo visual odometry on a KITTI-layout folder of rectified stereo pairs.");
  cli.option("--sequence", "DIR", "image_l/ (or image_0/), image_r/ (or image_1/), calib.txt",
             &sequence)
      .option("--simulated", "N", "N pairs rendered along the simulator's default drive",
              &simulated)
      .option("--output", "FILE", "the left camera's poses as a TUM trajectory (10 Hz stamps)",
              &output)
      .option("--max-frames", "N", "read at most N pairs", &max_frames)
      .flag("--verbose", "one line per pair: stereo points, matches, inliers, keyframe", &verbose);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (sequence.empty() == (simulated == 0))
    return cli.fail("exactly one of --sequence and --simulated is required");

  std::string error;
  const std::optional<PairSource> source =
      simulated ? simulatedSource(simulated, &error) : folderSource(sequence, &error);
  if (!source) return cli.fail(error);
  StereoOdometry odometry(source->camera, StereoOdometryParams());
  Trajectory estimate;
  std::vector<double> input_ms, features_ms, matching_ms, pose_ms, inliers;
  for (size_t i = 0; i < source->pairs && i < max_frames; ++i) {
    cv::Mat left, right;
    const auto t0 = std::chrono::steady_clock::now();
    const bool read = source->read(i, left, right);
    input_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (!read) {
      std::cerr << "stereo_odometry: pair " << i << " is missing or mismatched; skipped\n";
      continue;
    }
    const StereoOdometryResult r = odometry.track(left, right);
    estimate.push_back({0.1 * static_cast<double>(i), r.pose});
    features_ms.push_back(r.features_ms);
    matching_ms.push_back(r.matching_ms);
    pose_ms.push_back(r.pose_ms);
    if (i > 0) inliers.push_back(r.inliers);
    if (verbose)
      std::printf("pair %zu: %d stereo points, %d matches, %d inliers%s%s\n", i, r.stereo_points,
                  r.matches, r.inliers, r.tracked ? "" : ", NOT TRACKED",
                  r.new_keyframe ? ", new keyframe" : "");
  }
  std::printf(
      "%s, %zu pairs: %zu tracked, %zu not; %.0f inliers (median); ms per pair (median): "
      "features %.1f, matching %.1f, pose %.1f (%s %.1f)\n",
      source->name.c_str(), estimate.size(), odometry.tracked(), odometry.lost(), median(inliers),
      median(features_ms), median(matching_ms), median(pose_ms),
      simulated ? "rendering" : "reading", median(input_ms));
  if (!output.empty() && !writeTumTrajectory(output, estimate))
    std::cerr << "stereo_odometry: cannot write " << output << "\n";
  if (!source->truth.empty()) reportErrors(estimate, source->truth);
  return 0;
}
