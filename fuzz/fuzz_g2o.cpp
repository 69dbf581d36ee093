// .g2o text, through the stream reader, then (when it read) the writer and a second read.
#include <cstdint>
#include <sstream>
#include <string>

#include "osm_graph_slam/graph/g2o_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  osm_graph_slam::PoseGraph graph;
  const osm_graph_slam::G2oReadResult read = osm_graph_slam::readG2o(in, &graph);
  if (!read.ok) return 0;
  std::ostringstream out;
  osm_graph_slam::writeG2o(graph, out);
  std::istringstream again(out.str());
  osm_graph_slam::PoseGraph copy;
  osm_graph_slam::readG2o(again, &copy);
  return 0;
}
