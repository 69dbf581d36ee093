// mulran2bag: MulRan sequence folder -> rosbag (see doc/simulator.md).
#include <cstdio>
#include <string>

#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

int main(int argc, char** argv) {
  MulranBagOptions o;
  tools::CommandLine cli("mulran2bag", "MulRan sequence folder -> rosbag (see doc/simulator.md).");
  cli.positional("SEQUENCE_DIR", "the sequence: global_pose.csv and sensor_data/", &o.root)
      .positional("OUT.bag", "the bag to write", &o.bag_path)
      .flag("--absolute-gt",
            "global_pose.csv as is (UTM-like numbers; default: relative to the first pose)",
            &o.absolute_ground_truth)
      .flag("--skip-missing", "skip scans and images listed in data_stamp.csv but absent",
            &o.skip_missing);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  const BagConversionResult r = convertMulranToBag(o, stderrProgressBar("mulran2bag"));
  if (!r.ok) {
    std::fprintf(stderr, "\nmulran2bag: %s\n", r.error.c_str());
    return 1;
  }
  std::fprintf(stderr,
               "mulran2bag: wrote %s: %zu clouds, %zu radar images, %zu gps, %zu imu, %zu ground "
               "truth\n",
               o.bag_path.c_str(), r.clouds, r.images, r.gps, r.imu, r.ground_truth);
  return 0;
}
