// mulran2bag: MulRan sequence folder -> rosbag (see doc/simulator.md).
#include <cstdio>
#include <string>

#include "osm_graph_slam/drive_io/dataset_bag.h"

using namespace osm_graph_slam;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: mulran2bag <sequence_dir> <out.bag> [--absolute-gt] [--skip-missing]\n"
                 "  sequence_dir holds global_pose.csv and sensor_data/\n");
    return 2;
  }
  MulranBagOptions o;
  o.root = argv[1];
  o.bag_path = argv[2];
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--absolute-gt")
      o.absolute_ground_truth = true;
    else if (a == "--skip-missing")
      o.skip_missing = true;
    else {
      std::fprintf(stderr, "mulran2bag: unknown option %s\n", a.c_str());
      return 2;
    }
  }
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
