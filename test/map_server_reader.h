#pragma once
// A reader of map_server's map pair (wiki.ros.org/map_server, "Map format"), written from that
// page for the tests because map_server is not in Debian: the YAML's image, resolution, origin,
// thresholds and negate; a P5 PGM; trinary interpretation, p = (255 - value) / 255 without negate,
// occupied above occupied_thresh, free below free_thresh, unknown between; image row 0 = top.
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace osm_graph_slam {
namespace test {

struct MapServerMap {
  double resolution = 0.0;
  double origin_x = 0.0, origin_y = 0.0, origin_yaw = 0.0;
  int width = 0, height = 0;
  /// As map_server's OccupancyGrid: row 0 at the lowest y; 100 occupied, 0 free, -1 unknown.
  std::vector<int8_t> cells;
  std::string error;
  int8_t at(int x, int y) const { return cells[static_cast<size_t>(y) * width + x]; }
};

/// Skips whitespace and '#' comments between PGM header fields.
inline std::string pgmToken(std::istream& in) {
  std::string token;
  while (in) {
    const int c = in.peek();
    if (c == '#') {
      std::string comment;
      std::getline(in, comment);
    } else if (std::isspace(c)) {
      in.get();
    } else {
      break;
    }
  }
  in >> token;
  return token;
}

inline MapServerMap readMapServerMap(const std::string& yaml_path) {
  MapServerMap map;
  const YAML::Node yaml = YAML::LoadFile(yaml_path);
  const auto origin = yaml["origin"].as<std::vector<double>>();
  map.resolution = yaml["resolution"].as<double>();
  map.origin_x = origin.at(0), map.origin_y = origin.at(1), map.origin_yaw = origin.at(2);
  const double occupied = yaml["occupied_thresh"].as<double>();
  const double free = yaml["free_thresh"].as<double>();
  const bool negate = yaml["negate"].as<int>() != 0;
  std::filesystem::path image = yaml["image"].as<std::string>();
  if (image.is_relative()) image = std::filesystem::path(yaml_path).parent_path() / image;

  std::ifstream in(image, std::ios::binary);
  if (pgmToken(in) != "P5") {
    map.error = "not a binary PGM (P5)";
    return map;
  }
  map.width = std::stoi(pgmToken(in));
  map.height = std::stoi(pgmToken(in));
  const int max_value = std::stoi(pgmToken(in));
  in.get();  // the single whitespace before the raster
  std::vector<unsigned char> raster(static_cast<size_t>(map.width) * map.height);
  in.read(reinterpret_cast<char*>(raster.data()), static_cast<std::streamsize>(raster.size()));
  if (max_value != 255 || in.gcount() != static_cast<std::streamsize>(raster.size())) {
    map.error = "PGM raster truncated or not 8-bit";
    return map;
  }
  map.cells.resize(raster.size());
  for (int row = 0; row < map.height; ++row)
    for (int x = 0; x < map.width; ++x) {
      const double value = raster[static_cast<size_t>(row) * map.width + x];
      const double p = negate ? value / 255.0 : (255.0 - value) / 255.0;
      const int y = map.height - 1 - row;
      map.cells[static_cast<size_t>(y) * map.width + x] = p > occupied ? 100 : p < free ? 0 : -1;
    }
  return map;
}

}  // namespace test
}  // namespace osm_graph_slam
