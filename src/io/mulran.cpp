#include "osm_graph_slam/io/mulran.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace osm_graph_slam {
namespace {

bool fail(std::string* error, const std::string& msg) {
  if (error) *error = msg;
  return false;
}

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) {
    const auto b = cell.find_first_not_of(" \t\r");
    const auto e = cell.find_last_not_of(" \t\r");
    out.push_back(b == std::string::npos ? std::string() : cell.substr(b, e - b + 1));
  }
  return out;
}

bool toInt64(const std::string& s, int64_t& v) {
  char* end = nullptr;
  v = std::strtoll(s.c_str(), &end, 10);
  return end != s.c_str() && *end == '\0';
}

bool toDouble(const std::string& s, double& v) {
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0';
}

/// Calls row(cells, line_no) for every non-empty line; row returns false on a malformed line.
template <typename RowFn>
bool forEachCsvRow(const std::string& path, std::string* error, RowFn row) {
  std::ifstream in(path);
  if (!in) return fail(error, "cannot open MulRan file '" + path + "'");
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto cells = splitCsv(line);
    if (!row(cells)) {
      return fail(error, "malformed MulRan file '" + path + "' line " + std::to_string(line_no) +
                             ": '" + line + "'");
    }
  }
  return true;
}

bool parseNumbers(const std::vector<std::string>& cells, size_t first, std::vector<double>& out) {
  out.clear();
  for (size_t i = first; i < cells.size(); ++i) {
    double v;
    if (!toDouble(cells[i], v)) return false;
    out.push_back(v);
  }
  return true;
}

}  // namespace

std::string MulranSequence::ousterPath(int64_t stamp_ns) const {
  return (fs::path(root) / "sensor_data" / "Ouster" / (std::to_string(stamp_ns) + ".bin")).string();
}

std::string MulranSequence::radarPolarPath(int64_t stamp_ns) const {
  return (fs::path(root) / "sensor_data" / "radar" / "polar" / (std::to_string(stamp_ns) + ".png"))
      .string();
}

bool readMulranSequence(const std::string& root, MulranSequence& seq, std::string* error) {
  if (!fs::is_directory(root)) return fail(error, "MulRan sequence '" + root + "' is missing");
  seq = MulranSequence();
  seq.root = root;
  const fs::path data = fs::path(root) / "sensor_data";

  bool ok = forEachCsvRow((data / "data_stamp.csv").string(), error, [&](const auto& c) {
    MulranStamp s;
    if (c.size() != 2 || !toInt64(c[0], s.stamp_ns) || c[1].empty()) return false;
    s.sensor = c[1];
    seq.stamps.push_back(s);
    return true;
  });
  if (!ok) return false;

  ok = forEachCsvRow((data / "gps.csv").string(), error, [&](const auto& c) {
    MulranGps g;
    std::vector<double> v;
    if (c.size() != 13 || !toInt64(c[0], g.stamp_ns) || !parseNumbers(c, 1, v)) return false;
    g.lat = v[0];
    g.lon = v[1];
    g.alt = v[2];
    for (int i = 0; i < 9; ++i) g.covariance[i] = v[3 + i];
    seq.gps.push_back(g);
    return true;
  });
  if (!ok) return false;

  ok = forEachCsvRow((data / "xsens_imu.csv").string(), error, [&](const auto& c) {
    MulranImu m;
    std::vector<double> v;
    if ((c.size() != 8 && c.size() != 17) || !toInt64(c[0], m.stamp_ns) || !parseNumbers(c, 1, v)) {
      return false;
    }
    m.orientation = Eigen::Quaterniond(v[3], v[0], v[1], v[2]);
    if (std::abs(m.orientation.norm() - 1.0) > 1e-2) return false;
    m.orientation.normalize();
    m.euler = Eigen::Vector3d(v[4], v[5], v[6]);
    if (c.size() == 17) {
      m.has_rates = true;
      m.gyro = Eigen::Vector3d(v[7], v[8], v[9]);
      m.acc = Eigen::Vector3d(v[10], v[11], v[12]);
      m.mag = Eigen::Vector3d(v[13], v[14], v[15]);
    }
    seq.imu.push_back(m);
    return true;
  });
  if (!ok) return false;

  const fs::path pose_path = fs::path(root) / "global_pose.csv";
  if (fs::exists(pose_path)) {
    ok = forEachCsvRow(pose_path.string(), error, [&](const auto& c) {
      MulranPose p;
      std::vector<double> v;
      if (c.size() != 13 || !toInt64(c[0], p.stamp_ns) || !parseNumbers(c, 1, v)) return false;
      Eigen::Matrix3d R;
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) R(r, k) = v[4 * r + k];
        p.pose.translation()(r) = v[4 * r + 3];
      }
      // Orthonormalise: the CSV holds rounded values.
      Eigen::Quaterniond q(R);
      p.pose.linear() = q.normalized().toRotationMatrix();
      seq.poses.push_back(p);
      return true;
    });
    if (!ok) return false;
  }
  return true;
}

}  // namespace osm_graph_slam
