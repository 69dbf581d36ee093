// MulRan CSV files. The first input byte picks the file that gets the rest of the input
// (data_stamp.csv, gps.csv, xsens_imu.csv, global_pose.csv); the others hold one valid row.
#include <cstdint>
#include <filesystem>
#include <string>

#include "fuzz_util.h"
#include "osm_graph_slam/io/mulran.h"

namespace {

const char* const kNames[] = {"sensor_data/data_stamp.csv", "sensor_data/gps.csv",
                              "sensor_data/xsens_imu.csv", "global_pose.csv"};
const char* const kValid[] = {"1561000444390857630,ouster\n1561000444391000000,gps\n",
                              "1561000444391000000,37.3,127.0,30.1,1,0,0,0,1,0,0,0,1\n",
                              "1561000444392000000,0,0,0,1,0.1,0.2,0.3\n",
                              "1561000444390857630,1,0,0,353000,0,1,0,4026000,0,0,1,19\n"};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const std::string root = [] {
    const std::string r = ogs_fuzz::scratchPath("mulran");
    std::filesystem::create_directories(r + "/sensor_data");
    return r;
  }();
  const int target = data[0] % 4;
  for (int i = 0; i < 4; ++i) {
    const std::string path = root + "/" + kNames[i];
    if (i == target) {
      ogs_fuzz::writeFile(path, data + 1, size - 1);
    } else {
      ogs_fuzz::writeFile(path, std::string(kValid[i]));
    }
  }
  osm_graph_slam::MulranSequence sequence;
  std::string error;
  if (osm_graph_slam::readMulranSequence(root, sequence, &error) && !sequence.stamps.empty()) {
    sequence.ousterPath(sequence.stamps.front().stamp_ns);
  }
  return 0;
}
