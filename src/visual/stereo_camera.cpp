#include "osm_graph_slam/visual/stereo_camera.h"

#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace osm_graph_slam {

std::optional<StereoCamera> readKittiStereoCalibration(const std::string& path,
                                                       std::string* error) {
  auto fail = [&](const std::string& why) -> std::optional<StereoCamera> {
    if (error) *error = path + ": " + why;
    return std::nullopt;
  };
  std::ifstream in(path);
  if (!in) return fail("cannot be opened");
  // Rows keyed "P0:", "P1:" (the odometry benchmark) or, without keys, the first two rows of
  // 12 numbers (P0 then P1).
  std::map<std::string, std::array<double, 12>> rows;
  std::vector<std::array<double, 12>> unkeyed;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string key;
    if (!(s >> key)) continue;
    const bool keyed = key.back() == ':';
    if (keyed && key != "P0:" && key != "P1:") continue;
    if (!keyed) s = std::istringstream(line);
    std::array<double, 12> p{};
    bool complete = true;
    for (double& v : p) complete = complete && static_cast<bool>(s >> v);
    if (!complete) return fail("a projection row has fewer than 12 numbers");
    if (keyed)
      rows[key] = p;
    else
      unkeyed.push_back(p);
  }
  if (!rows.count("P0:") && unkeyed.size() >= 2) {
    rows["P0:"] = unkeyed[0];
    rows["P1:"] = unkeyed[1];
  }
  if (!rows.count("P0:") || !rows.count("P1:"))
    return fail("no P0 and P1 rows (keyed \"P0:\", or the first two rows of 12 numbers)");
  const auto& p0 = rows["P0:"];
  const auto& p1 = rows["P1:"];
  StereoCamera c;
  c.fx = p0[0];
  c.cx = p0[2];
  c.fy = p0[5];
  c.cy = p0[6];
  if (!(c.fx > 0.0) || !(c.fy > 0.0)) return fail("P0 has no positive focal length");
  c.baseline = -p1[3] / p1[0];
  if (!(c.baseline > 0.0) || !std::isfinite(c.baseline))
    return fail("P1 gives no positive baseline (its fourth column is -fx * baseline)");
  return c;
}

}  // namespace osm_graph_slam
