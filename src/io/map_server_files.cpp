#include "osm_graph_slam/io/map_server_files.h"

#include <iomanip>
#include <sstream>

namespace osm_graph_slam {
namespace {

constexpr int kOccupiedPercent = 65;  ///< occupied_thresh 0.65
constexpr int kFreePercent = 19;      ///< below free_thresh 0.196
constexpr unsigned char kOccupiedPixel = 0, kFreePixel = 254, kUnknownPixel = 205;

}  // namespace

MapServerCell mapServerClass(int8_t value) {
  if (value < 0) return MapServerCell::kUnknown;
  if (value >= kOccupiedPercent) return MapServerCell::kOccupied;
  if (value <= kFreePercent) return MapServerCell::kFree;
  return MapServerCell::kUnknown;
}

std::string mapServerPgm(const OccupancyGridImage& grid) {
  std::ostringstream header;
  header << "P5\n# osm_graph_slam occupancy grid, " << grid.resolution << " m/pixel\n"
         << grid.width << ' ' << grid.height << "\n255\n";
  std::string out = header.str();
  out.reserve(out.size() + static_cast<size_t>(grid.width) * grid.height);
  for (int row = 0; row < grid.height; ++row) {
    const int y = grid.height - 1 - row;  // image row 0 is the top: the highest y
    for (int x = 0; x < grid.width; ++x) {
      switch (mapServerClass(grid.at(x, y))) {
        case MapServerCell::kOccupied:
          out.push_back(static_cast<char>(kOccupiedPixel));
          break;
        case MapServerCell::kFree:
          out.push_back(static_cast<char>(kFreePixel));
          break;
        case MapServerCell::kUnknown:
          out.push_back(static_cast<char>(kUnknownPixel));
          break;
      }
    }
  }
  return out;
}

std::string mapServerYaml(const OccupancyGridImage& grid, const std::string& image_name) {
  std::ostringstream os;
  os << std::setprecision(12) << "image: " << image_name << "\nresolution: " << grid.resolution
     << "\norigin: [" << grid.origin.x() << ", " << grid.origin.y() << ", 0.0]\n"
     << "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  return os.str();
}

}  // namespace osm_graph_slam
