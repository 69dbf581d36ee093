// readGraphDump: the first input byte picks the file that gets the rest of the input
// (keyframes.csv, segments.csv, loops.csv, origin.txt, initial_heading.txt,
// buildings_prior.geojson, floors.csv); the others hold valid content.
#include <cstdint>
#include <filesystem>
#include <string>

#include "fuzz_util.h"
#include "osm_graph_slam/slam/graph_dump.h"

namespace {

const char* const kNames[] = {"keyframes.csv", "segments.csv",        "loops.csv",
                              "origin.txt",    "initial_heading.txt", "buildings_prior.geojson",
                              "floors.csv"};
constexpr int kFiles = sizeof(kNames) / sizeof(kNames[0]);
const char* const kValid[] = {
    "# id stamp distance pose(3x4) fitness roll pitch reanchored\n"
    "0 0.0 0.0 1 0 0 0 0 1 0 0 0 0 1 0 0.1 nan nan 0\n"
    "1 1.0 1.5 1 0 0 1.5 0 1 0 0 0 0 1 0 0.1 0.01 0.02 1\n",
    "0 -1 -1 1 -1 12\n1 -1 2 3 2 7\n",
    "1 0 1 0 0 0 0 1 0 0 0 0 1 0 "
    "1 0 0 0 0 0 0 1 0 0 0 0 0 0 1 0 0 0 0 0 0 1 0 0 0 0 0 0 1 0 0 0 0 0 0 1\n",
    "49.011 8.4228 112.8\n",
    "-1.2219\n",
    "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\",\"properties\":{\"id\":7},"
    "\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[[[8.4228,49.0110],[8.4230,49.0110],"
    "[8.4230,49.0112],[8.4228,49.0110]]]}}]}\n",
    "# keyframe_id a b c d\n1 0.01 0 0.9999 1.73\n"};
static_assert(sizeof(kValid) / sizeof(kValid[0]) == kFiles, "one valid content per file");

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const std::string dir = [] {
    const std::string d = ogs_fuzz::scratchPath("dump");
    std::filesystem::create_directories(d);
    return d;
  }();
  const int target = data[0] % kFiles;
  for (int i = 0; i < kFiles; ++i) {
    const std::string path = dir + "/" + kNames[i];
    if (i == target) {
      ogs_fuzz::writeFile(path, data + 1, size - 1);
    } else {
      ogs_fuzz::writeFile(path, std::string(kValid[i]));
    }
  }
  osm_graph_slam::GraphDump dump;
  std::string error;
  osm_graph_slam::readGraphDump(dir, dump, &error);
  return 0;
}
