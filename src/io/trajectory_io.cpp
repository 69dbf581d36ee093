#include "osm_graph_slam/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace osm_graph_slam {
namespace {

std::vector<double> parseNumbers(const std::string& line, bool* ok) {
  std::istringstream ss(line);
  std::vector<double> values;
  std::string token;
  *ok = true;
  while (ss >> token) {
    try {
      size_t used = 0;
      values.push_back(std::stod(token, &used));
      if (used != token.size()) *ok = false;
    } catch (const std::exception&) {
      *ok = false;
    }
  }
  return values;
}

bool isBlankOrComment(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

template <typename RowFn>
TrajectoryReadResult readRows(const std::string& path, RowFn&& row_fn) {
  TrajectoryReadResult result;
  std::ifstream in(path);
  if (!in) {
    result.error = "cannot open trajectory file '" + path + "'";
    return result;
  }
  std::string line;
  size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (isBlankOrComment(line)) continue;
    bool ok = false;
    const std::vector<double> v = parseNumbers(line, &ok);
    std::string why;
    if (!ok || !row_fn(v, result.trajectory, &why)) {
      result.error = path + ":" + std::to_string(line_no) + ": " +
                     (ok ? why : std::string("not a number")) + " in '" + line + "'";
      return result;
    }
  }
  result.ok = true;
  return result;
}

Eigen::Isometry3d poseFrom12(const double* v) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[4 * r + c];
  Eigen::Isometry3d pose(m);
  // Re-orthonormalise: KITTI rows carry ~1e-9 rounding that breaks exact inverse identities.
  Eigen::Quaterniond q(pose.rotation());
  pose.linear() = q.normalized().toRotationMatrix();
  return pose;
}

}  // namespace

TrajectoryReadResult readKittiPoses(const std::string& path) {
  return readRows(path, [](const std::vector<double>& v, Trajectory& t, std::string* why) {
    if (v.size() != 12 && v.size() != 13) {
      *why = "expected 12 or 13 numbers, got " + std::to_string(v.size());
      return false;
    }
    StampedPose sp;
    const bool timed = v.size() == 13;
    sp.stamp = timed ? v[0] : 0.1 * static_cast<double>(t.size());
    sp.pose = poseFrom12(v.data() + (timed ? 1 : 0));
    t.push_back(sp);
    return true;
  });
}

TrajectoryReadResult readTumTrajectory(const std::string& path) {
  return readRows(path, [](const std::vector<double>& v, Trajectory& t, std::string* why) {
    if (v.size() != 8) {
      *why = "expected 8 numbers (time tx ty tz qx qy qz qw), got " + std::to_string(v.size());
      return false;
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 1e-9) {
      *why = "zero quaternion";
      return false;
    }
    StampedPose sp;
    sp.stamp = v[0];
    sp.pose = Eigen::Isometry3d::Identity();
    sp.pose.linear() = q.normalized().toRotationMatrix();
    sp.pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    t.push_back(sp);
    return true;
  });
}

TrajectoryReadResult readTrajectory(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (isBlankOrComment(line)) continue;
    bool ok = false;
    const size_t n = parseNumbers(line, &ok).size();
    return n == 8 ? readTumTrajectory(path) : readKittiPoses(path);
  }
  TrajectoryReadResult empty;
  empty.error = in ? "trajectory file '" + path + "' is empty" : "cannot open '" + path + "'";
  return empty;
}

bool writeKittiPoses(const std::string& path, const Trajectory& trajectory, bool with_time,
                     std::string* error) {
  std::ostringstream out;
  out << std::setprecision(12);
  for (const auto& sp : trajectory) {
    if (with_time) out << std::setprecision(17) << sp.stamp << ' ' << std::setprecision(12);
    const Eigen::Matrix4d m = sp.pose.matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) out << m(r, c) << ((r == 2 && c == 3) ? '\n' : ' ');
  }
  return writeFileAtomically(path, out.str(), error);
}

bool writeTumTrajectory(const std::string& path, const Trajectory& trajectory, std::string* error) {
  std::ostringstream out;
  out << "# time tx ty tz qx qy qz qw\n" << std::setprecision(12);
  for (const auto& sp : trajectory) {
    const Eigen::Quaterniond q(sp.pose.rotation());
    const Eigen::Vector3d t = sp.pose.translation();
    out << std::setprecision(17) << sp.stamp << std::setprecision(12) << ' ' << t.x() << ' '
        << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w()
        << '\n';
  }
  return writeFileAtomically(path, out.str(), error);
}

bool interpolatePose(const Trajectory& poses, double t, double max_gap, Eigen::Isometry3d& out) {
  if (poses.empty()) return false;
  auto it = std::lower_bound(poses.begin(), poses.end(), t,
                             [](const StampedPose& p, double x) { return p.stamp < x; });
  if (it == poses.begin() || it == poses.end()) {
    const StampedPose& end = it == poses.begin() ? poses.front() : poses.back();
    if (std::abs(end.stamp - t) > max_gap) return false;
    out = end.pose;
    return true;
  }
  const StampedPose &b = *it, &a = *(it - 1);
  if (b.stamp - a.stamp > max_gap) return false;
  const double s = (t - a.stamp) / (b.stamp - a.stamp);
  out = Eigen::Isometry3d::Identity();
  out.translation() = (1 - s) * a.pose.translation() + s * b.pose.translation();
  out.linear() = Eigen::Quaterniond(a.pose.linear())
                     .slerp(s, Eigen::Quaterniond(b.pose.linear()))
                     .toRotationMatrix();
  return true;
}

}  // namespace osm_graph_slam
