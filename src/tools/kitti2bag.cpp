// kitti2bag: KITTI raw drive, KITTI odometry sequence, or a folder of KITTI .bin scans with one
// georeference -> rosbag (see doc/simulator.md).
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/drive_io/dataset_bag.h"

using namespace osm_graph_slam;

namespace {

void usage() {
  std::fprintf(
      stderr,
      "usage: kitti2bag <drive_or_sequence_dir> <out.bag> [options]\n"
      "       kitti2bag --scans DIR (--origin-oxts FILE | --origin LAT,LON,ALT[,YAW_DEG])\n"
      "                 [--rate HZ] [--calib FILE] [--start-time SEC] <out.bag>\n"
      "  The layout is detected: velodyne_points/ -> KITTI raw, velodyne/ -> odometry.\n"
      "  --raw | --odometry     force the layout\n"
      "  --calib-dir DIR        raw: folder of calib_*.txt (default: drive dir, parent)\n"
      "  --poses FILE           odometry: poses file (default: ../../poses/NN.txt)\n"
      "  --start-time SEC       odometry: stamp of times.txt 0 (default 1.0); --scans: stamp of\n"
      "                         the first scan (default: the OXTS record's timestamps.txt line\n"
      "                         when it has one, else 2011-09-26 00:00:00 UTC)\n"
      "  --scans DIR            a folder of .bin scans without per-scan OXTS: velodyne_points\n"
      "                         at start + i/rate, ONE gps/fix at the first scan (the map\n"
      "                         origin), ONE imu/data there when the origin has an attitude\n"
      "  --origin-oxts FILE     --scans: the OXTS record (30 values) of the first scan\n"
      "  --origin LAT,LON,ALT[,YAW_DEG]  --scans: the first scan's position (yaw: ENU, deg)\n"
      "  --rate HZ              --scans: scan rate (default 10)\n"
      "  --calib FILE           --scans: calib_imu_to_velo.txt or a tracking-layout file with\n"
      "                         Tr_imu_to_velo (base_link = the OXTS unit); default: none\n"
      "                         (base_link = velo_link)\n");
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> positional;
  std::string mode, calib_dir, poses, scans, origin_oxts, origin, calib;
  std::optional<double> start_time;
  double rate = 10.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "kitti2bag: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    auto number = [&]() -> double {
      const std::string text = next();
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (end == text.c_str() || *end != '\0') {
        std::fprintf(stderr, "kitti2bag: %s takes a number, not '%s'\n", a.c_str(), text.c_str());
        std::exit(2);
      }
      return v;
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
      start_time = number();
    else if (a == "--scans")
      scans = next();
    else if (a == "--origin-oxts")
      origin_oxts = next();
    else if (a == "--origin")
      origin = next();
    else if (a == "--rate")
      rate = number();
    else if (a == "--calib")
      calib = next();
    else if (a == "-h" || a == "--help") {
      usage();
      return 0;
    } else if (a.rfind("--", 0) == 0) {
      std::fprintf(stderr, "kitti2bag: unknown option '%s'\n", a.c_str());
      usage();
      return 2;
    } else {
      positional.push_back(a);
    }
  }

  BagConversionResult r;
  std::string bag;
  if (!scans.empty()) {
    if (positional.size() != 1 || !mode.empty() || !calib_dir.empty() || !poses.empty()) {
      std::fprintf(stderr,
                   "kitti2bag: --scans takes exactly one <out.bag> and none of --raw, --odometry, "
                   "--calib-dir, --poses\n");
      usage();
      return 2;
    }
    if (start_time && !(*start_time > 0.0)) {
      std::fprintf(stderr, "kitti2bag: --start-time must be > 0 (rosbag rejects stamp 0)\n");
      return 2;
    }
    ScanFolderBagOptions o;
    o.scans_dir = scans;
    o.origin_oxts = origin_oxts;
    o.origin = origin;
    o.calib_path = calib;
    o.rate = rate;
    if (start_time) o.start_time = *start_time;
    o.bag_path = bag = positional[0];
    r = convertScanFolderToBag(o, stderrProgressBar("kitti2bag scans"));
    for (const std::string& w : r.warnings)
      std::fprintf(stderr, "kitti2bag: warning: %s\n", w.c_str());
  } else {
    if (!origin_oxts.empty() || !origin.empty() || !calib.empty() || rate != 10.0) {
      std::fprintf(stderr,
                   "kitti2bag: --origin-oxts, --origin, --calib and --rate need --scans DIR\n");
      return 2;
    }
    if (positional.size() != 2) {
      usage();
      return 2;
    }
    const std::string input = positional[0];
    bag = positional[1];
    if (mode.empty()) {
      namespace fs = std::filesystem;
      if (fs::is_directory(fs::path(input) / "velodyne_points"))
        mode = "raw";
      else if (fs::is_directory(fs::path(input) / "velodyne"))
        mode = "odometry";
      else {
        std::fprintf(stderr,
                     "kitti2bag: '%s' has neither velodyne_points/ (raw) nor velodyne/ "
                     "(odometry); a folder of .bin scans needs --scans\n",
                     input.c_str());
        return 1;
      }
    }
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
      if (start_time) o.start_time = *start_time;
      r = convertKittiOdometryToBag(o, stderrProgressBar("kitti2bag odometry"));
    }
  }
  if (!r.ok) {
    std::fprintf(stderr, "\nkitti2bag: %s\n", r.error.c_str());
    return 1;
  }
  std::fprintf(stderr, "kitti2bag: wrote %s: %zu clouds, %zu gps, %zu imu, %zu ground truth",
               bag.c_str(), r.clouds, r.gps, r.imu, r.ground_truth);
  if (!scans.empty())
    std::fprintf(stderr, ", %zu scans skipped, first stamp %.9f", r.skipped, r.first_stamp);
  std::fprintf(stderr, "\n");
  return 0;
}
