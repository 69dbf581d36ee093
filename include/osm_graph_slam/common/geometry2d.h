#pragma once
// Small 2D types shared by lines/, osm/, graph/, slam/ and sim/ (Eigen only, header-light).
#include <Eigen/Core>
#include <cmath>
#include <vector>

namespace osm_graph_slam {

/// Wraps an angle to (-pi, pi].
inline double wrapAngle(double a) {
  a = std::fmod(a + M_PI, 2.0 * M_PI);
  if (a <= 0.0) a += 2.0 * M_PI;
  return a - M_PI;
}

/// SE(2) pose: a point p in this frame maps to R(theta) p + (x, y) in the parent frame.
struct Pose2 {
  double x = 0.0, y = 0.0, theta = 0.0;

  Pose2() = default;
  Pose2(double x_, double y_, double theta_) : x(x_), y(y_), theta(theta_) {}

  Eigen::Vector2d translation() const { return {x, y}; }
  Eigen::Matrix2d rotation() const {
    const double c = std::cos(theta), s = std::sin(theta);
    Eigen::Matrix2d r;
    r << c, -s, s, c;
    return r;
  }
  Eigen::Vector2d transform(const Eigen::Vector2d& p) const {
    return rotation() * p + translation();
  }
  Pose2 operator*(const Pose2& o) const {
    const Eigen::Vector2d t = transform(o.translation());
    return {t.x(), t.y(), wrapAngle(theta + o.theta)};
  }
  Pose2 inverse() const {
    const Eigen::Vector2d t = -(rotation().transpose() * translation());
    return {t.x(), t.y(), wrapAngle(-theta)};
  }
};

/// A 2D line segment (a wall).
struct LineSegment2 {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
  unsigned support = 0;  ///< points supporting it (0 for map segments)

  LineSegment2() = default;
  LineSegment2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, unsigned n = 0)
      : start(a), end(b), support(n) {}

  double length() const { return (end - start).norm(); }
  Eigen::Vector2d direction() const {
    const double l = length();
    return l > 0.0 ? Eigen::Vector2d((end - start) / l) : Eigen::Vector2d(1.0, 0.0);
  }
  Eigen::Vector2d midpoint() const { return 0.5 * (start + end); }
  LineSegment2 transformed(const Pose2& T) const {
    return {T.transform(start), T.transform(end), support};
  }
};

using Polygon2 = std::vector<Eigen::Vector2d>;  ///< closed ring, first vertex not repeated

}  // namespace osm_graph_slam
