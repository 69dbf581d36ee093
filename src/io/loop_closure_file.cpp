#include "osm_graph_slam/io/loop_closure_file.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "osm_graph_slam/io/trajectory_io.h"

namespace osm_graph_slam {

bool writeLoopClosures(const std::string& path, const std::vector<StampedLoopClosure>& loops,
                       std::string* error) {
  std::ostringstream os;
  os << "# from_stamp to_stamp tx ty tz qx qy qz qw (from keyframe in the to keyframe's frame)\n";
  char row[320];
  for (const auto& l : loops) {
    const Eigen::Quaterniond q(l.relative_pose.linear());
    const Eigen::Vector3d t = l.relative_pose.translation();
    std::snprintf(row, sizeof(row), "%.9f %.9f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", l.from_stamp,
                  l.to_stamp, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    os << row;
  }
  return writeFileAtomically(path, os.str(), error);
}

LoopClosureReadResult readLoopClosures(const std::string& path) {
  LoopClosureReadResult out;
  std::ifstream in(path);
  if (!in) {
    out.error = "cannot open loop closure file '" + path + "'";
    return out;
  }
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream row(line);
    double v[9] = {};
    int n = 0;
    while (n < 9 && row >> v[n] && std::isfinite(v[n])) ++n;
    std::string extra;
    const Eigen::Quaterniond q(v[8], v[5], v[6], v[7]);
    if (n != 9 || (row >> extra) || std::abs(q.norm() - 1.0) > 1e-3) {
      out.error = path + ":" + std::to_string(number) +
                  ": expected 9 finite numbers 'from_stamp to_stamp tx ty tz qx qy qz qw' with a "
                  "unit quaternion";
      out.loops.clear();
      return out;
    }
    StampedLoopClosure l;
    l.from_stamp = v[0];
    l.to_stamp = v[1];
    l.relative_pose.linear() = q.normalized().toRotationMatrix();
    l.relative_pose.translation() = Eigen::Vector3d(v[2], v[3], v[4]);
    out.loops.push_back(l);
  }
  out.ok = true;
  return out;
}

}  // namespace osm_graph_slam
