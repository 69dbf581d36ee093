// kitti2bag: KITTI raw drive or KITTI odometry sequence -> rosbag (see doc/simulator.md).
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "osm_graph_slam/ros/dataset_bag.h"

using namespace osm_graph_slam;

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: kitti2bag <drive_or_sequence_dir> <out.bag> [options]\n"
               "  The layout is detected: velodyne_points/ -> KITTI raw, velodyne/ -> odometry.\n"
               "  --raw | --odometry     force the layout\n"
               "  --calib-dir DIR        raw: folder of calib_*.txt (default: drive dir, parent)\n"
               "  --poses FILE           odometry: poses file (default: ../../poses/NN.txt)\n"
               "  --start-time SEC       odometry: stamp of times.txt 0 (default 1.0)\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    usage();
    return 2;
  }
  const std::string input = argv[1], bag = argv[2];
  std::string mode, calib_dir, poses;
  double start_time = 1.0;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "kitti2bag: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--raw")
      mode = "raw";
    else if (a == "--odometry")
      mode = "odometry";
    else if (a == "--calib-dir")
      calib_dir = next();
    else if (a == "--poses")
      poses = next();
    else if (a == "--start-time")
      start_time = std::atof(next().c_str());
    else {
      usage();
      return 2;
    }
  }
  if (mode.empty()) {
    namespace fs = std::filesystem;
    if (fs::is_directory(fs::path(input) / "velodyne_points"))
      mode = "raw";
    else if (fs::is_directory(fs::path(input) / "velodyne"))
      mode = "odometry";
    else {
      std::fprintf(stderr,
                   "kitti2bag: '%s' has neither velodyne_points/ (raw) nor velodyne/ "
                   "(odometry)\n",
                   input.c_str());
      return 1;
    }
  }
  BagConversionResult r;
  if (mode == "raw") {
    KittiRawBagOptions o;
    o.drive_dir = input;
    o.calib_dir = calib_dir;
    o.bag_path = bag;
    r = convertKittiRawToBag(o, stderrProgressBar("kitti2bag raw"));
  } else {
    KittiOdometryBagOptions o;
    o.sequence_dir = input;
    o.poses_path = poses;
    o.bag_path = bag;
    o.start_time = start_time;
    r = convertKittiOdometryToBag(o, stderrProgressBar("kitti2bag odometry"));
  }
  if (!r.ok) {
    std::fprintf(stderr, "\nkitti2bag: %s\n", r.error.c_str());
    return 1;
  }
  std::fprintf(stderr, "kitti2bag: wrote %s: %zu clouds, %zu gps, %zu imu, %zu ground truth\n",
               bag.c_str(), r.clouds, r.gps, r.imu, r.ground_truth);
  return 0;
}
