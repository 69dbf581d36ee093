// OSM files by path: the first input byte picks the suffix (.osm.pbf, .osm, .osm.gz, .osm.bz2),
// the rest is the file. PBF is the interesting one (protozero + zlib blobs through libosmium).
#include <cstdint>
#include <string>

#include "fuzz_util.h"
#include "osm_graph_slam/osm/osm_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kSuffixes[] = {".osm.pbf", ".osm", ".osm.gz", ".osm.bz2"};
  const std::string path = ogs_fuzz::scratchPath(std::string("in") + kSuffixes[data[0] % 4]);
  ogs_fuzz::writeFile(path, data + 1, size - 1);
  osm_graph_slam::OsmReadOptions options;
  options.max_objects = 10'000;
  options.max_nodes = 100'000;
  const osm_graph_slam::OsmData osm = osm_graph_slam::readOsmFile(path, options);
  std::remove(path.c_str());
  return osm.buildings.size() == static_cast<size_t>(-1);
}
