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
#include "support/command_line.h"

using namespace osm_graph_slam;

namespace {

struct Options {
  std::string input, output;  ///< the positional arguments, in order
  std::string mode, calib_dir, poses, scans, origin_oxts, origin, calib;
  std::optional<double> start_time;
  double rate = 10.0;
};

void declareOptions(tools::CommandLine& cli, Options& o) {
  cli.positional("DRIVE_OR_SEQUENCE_DIR",
                 "a KITTI raw drive or odometry sequence (with --scans: "
                 "the bag to write)",
                 &o.input, false)
      .positional("OUT.bag", "the bag to write", &o.output, false)
      .flag("--raw", "force the KITTI raw layout (default: detected, velodyne_points/)",
            [&o] { o.mode = "raw"; })
      .flag("--odometry", "force the KITTI odometry layout (default: detected, velodyne/)",
            [&o] { o.mode = "odometry"; })
      .option("--calib-dir", "DIR", "raw: the folder of calib_*.txt (default: drive dir, parent)",
              &o.calib_dir)
      .option("--poses", "FILE", "odometry: the poses file (default: ../../poses/NN.txt)", &o.poses)
      .option("--start-time", "SEC",
              "odometry: the stamp of times.txt 0 (default 1.0); --scans: the stamp of the first "
              "scan (default: the OXTS record's timestamps.txt line when it has one, else "
              "2011-09-26 00:00:00 UTC)",
              [&o](const std::string& v) {
                double t = 0.0;
                if (!tools::parseDouble(v, &t)) return "takes a number, not '" + v + "'";
                o.start_time = t;
                return std::string();
              })
      .option("--scans", "DIR",
              "a folder of .bin scans without per-scan OXTS: velodyne_points at start + i/rate, "
              "ONE gps/fix at the first scan (the map origin), ONE imu/data there when the "
              "origin has an attitude",
              &o.scans)
      .option("--origin-oxts", "FILE", "--scans: the OXTS record (30 values) of the first scan",
              &o.origin_oxts)
      .option("--origin", "LAT,LON,ALT[,YAW_DEG]",
              "--scans: the first scan's position (yaw: ENU, deg)", &o.origin)
      .option("--rate", "HZ", "--scans: the scan rate", &o.rate)
      .option("--calib", "FILE",
              "--scans: calib_imu_to_velo.txt or a tracking-layout file with Tr_imu_to_velo "
              "(base_link = the OXTS unit); default: none (base_link = velo_link)",
              &o.calib)
      .note(
          "usage: kitti2bag <drive_or_sequence_dir> <out.bag> [options]\n"
          "       kitti2bag --scans DIR (--origin-oxts FILE | --origin LAT,LON,ALT[,YAW_DEG])\n"
          "                 [--rate HZ] [--calib FILE] [--start-time SEC] <out.bag>\n"
          "The layout is detected: velodyne_points/ -> KITTI raw, velodyne/ -> odometry.");
}

/// --scans: one bag from a folder of scans and one georeference; an exit status on a usage error.
std::optional<int> convertScans(const tools::CommandLine& cli, const Options& opt,
                                const std::vector<std::string>& positional, BagConversionResult& r,
                                std::string& bag) {
  if (positional.size() != 1 || !opt.mode.empty() || !opt.calib_dir.empty() || !opt.poses.empty())
    return cli.fail(
        "--scans takes exactly one <out.bag> and none of --raw, --odometry, --calib-dir, --poses");
  if (opt.start_time && !(*opt.start_time > 0.0)) {
    std::fprintf(stderr, "kitti2bag: --start-time must be > 0 (rosbag rejects stamp 0)\n");
    return 2;
  }
  ScanFolderBagOptions o;
  o.scans_dir = opt.scans;
  o.origin_oxts = opt.origin_oxts;
  o.origin = opt.origin;
  o.calib_path = opt.calib;
  o.rate = opt.rate;
  if (opt.start_time) o.start_time = *opt.start_time;
  o.bag_path = bag = positional[0];
  r = convertScanFolderToBag(o, stderrProgressBar("kitti2bag scans"));
  for (const std::string& w : r.warnings)
    std::fprintf(stderr, "kitti2bag: warning: %s\n", w.c_str());
  return std::nullopt;
}

/// A KITTI raw drive or odometry sequence (layout detected unless forced); an exit status on a
/// usage error or an unknown layout.
std::optional<int> convertDataset(const tools::CommandLine& cli, Options opt,
                                  const std::vector<std::string>& positional,
                                  BagConversionResult& r, std::string& bag) {
  if (!opt.origin_oxts.empty() || !opt.origin.empty() || !opt.calib.empty() || opt.rate != 10.0) {
    std::fprintf(stderr,
                 "kitti2bag: --origin-oxts, --origin, --calib and --rate need --scans DIR\n");
    return 2;
  }
  if (positional.size() != 2) return cli.fail("<drive_or_sequence_dir> and <out.bag> are required");
  const std::string input = positional[0];
  bag = positional[1];
  std::string& mode = opt.mode;
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
    o.calib_dir = opt.calib_dir;
    o.bag_path = bag;
    r = convertKittiRawToBag(o, stderrProgressBar("kitti2bag raw"));
  } else {
    KittiOdometryBagOptions o;
    o.sequence_dir = input;
    o.poses_path = opt.poses;
    o.bag_path = bag;
    if (opt.start_time) o.start_time = *opt.start_time;
    r = convertKittiOdometryToBag(o, stderrProgressBar("kitti2bag odometry"));
  }
  return std::nullopt;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  tools::CommandLine cli("kitti2bag",
                         "KITTI raw drive, KITTI odometry sequence, or a folder of KITTI .bin "
                         "scans with one georeference -> rosbag (see doc/simulator.md).");
  declareOptions(cli, opt);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::vector<std::string> positional;
  for (const std::string* p : {&opt.input, &opt.output})
    if (!p->empty()) positional.push_back(*p);

  BagConversionResult r;
  std::string bag;
  const std::optional<int> exit_code = opt.scans.empty()
                                           ? convertDataset(cli, opt, positional, r, bag)
                                           : convertScans(cli, opt, positional, r, bag);
  if (exit_code) return *exit_code;
  if (!r.ok) {
    std::fprintf(stderr, "\nkitti2bag: %s\n", r.error.c_str());
    return 1;
  }
  std::fprintf(stderr, "kitti2bag: wrote %s: %zu clouds, %zu gps, %zu imu, %zu ground truth",
               bag.c_str(), r.clouds, r.gps, r.imu, r.ground_truth);
  if (!opt.scans.empty())
    std::fprintf(stderr, ", %zu scans skipped, first stamp %.9f", r.skipped, r.first_stamp);
  std::fprintf(stderr, "\n");
  return 0;
}
