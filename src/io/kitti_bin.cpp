#include "osm_graph_slam/io/kitti_bin.h"

#include <cstdio>
#include <fstream>
#include <vector>

namespace osm_graph_slam {
namespace {

bool fail(std::string* error, const std::string& msg) {
  if (error) *error = msg;
  return false;
}

}  // namespace

bool readKittiBin(const std::string& path, PointCloud& cloud, std::string* error) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return fail(error, "cannot open KITTI scan '" + path + "'");
  const std::streamsize bytes = in.tellg();
  if (bytes < 0 || bytes % 16 != 0) {
    return fail(error, "KITTI scan '" + path + "' has " + std::to_string(bytes) +
                           " bytes, not a multiple of 16 (x, y, z, reflectance float32)");
  }
  std::vector<float> raw(static_cast<size_t>(bytes) / sizeof(float));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(raw.data()), bytes)) {
    return fail(error, "short read on KITTI scan '" + path + "'");
  }
  const size_t n = raw.size() / 4;
  cloud.clear();
  cloud.resize(n);
  for (size_t i = 0; i < n; ++i) {
    PointT& p = cloud[i];
    p.x = raw[4 * i];
    p.y = raw[4 * i + 1];
    p.z = raw[4 * i + 2];
    p.intensity = raw[4 * i + 3];
  }
  cloud.width = static_cast<uint32_t>(n);
  cloud.height = 1;
  cloud.is_dense = false;  // reader does not check for NaN; the prefilter does
  return true;
}

bool writeKittiBin(const std::string& path, const PointCloud& cloud, std::string* error) {
  std::vector<float> raw;
  raw.reserve(cloud.size() * 4);
  for (const auto& p : cloud) {
    raw.insert(raw.end(), {p.x, p.y, p.z, p.intensity});
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return fail(error, "cannot write '" + tmp + "'");
    out.write(reinterpret_cast<const char*>(raw.data()),
              static_cast<std::streamsize>(raw.size() * sizeof(float)));
    if (!out) return fail(error, "write error on '" + tmp + "'");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return fail(error, "cannot rename '" + tmp + "' to '" + path + "'");
  }
  return true;
}

}  // namespace osm_graph_slam
