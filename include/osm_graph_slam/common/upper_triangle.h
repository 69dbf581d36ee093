#pragma once
// Symmetric matrices stored as their upper triangle, row by row: how g2o files, the graph dump
// and the KeyFrame message carry information matrices.
#include <Eigen/Core>
#include <ostream>
#include <vector>

namespace osm_graph_slam {

/// The upper triangle of a square matrix, row by row (n(n+1)/2 values).
inline std::vector<double> upperTriangle(const Eigen::MatrixXd& m) {
  std::vector<double> v;
  v.reserve(static_cast<size_t>(m.rows() * (m.rows() + 1) / 2));
  for (int r = 0; r < m.rows(); ++r)
    for (int c = r; c < m.cols(); ++c) v.push_back(m(r, c));
  return v;
}

/// The symmetric n×n matrix whose upper triangle starts at v[offset]; v must hold n(n+1)/2
/// values from there.
inline Eigen::MatrixXd upperTriangleToMatrix(const std::vector<double>& v, size_t offset, int n) {
  Eigen::MatrixXd m(n, n);
  size_t k = offset;
  for (int r = 0; r < n; ++r)
    for (int c = r; c < n; ++c) m(r, c) = m(c, r) = v[k++];
  return m;
}

/// The upper triangle written as " v1 v2 ..." with the stream's precision.
inline void writeUpperTriangle(std::ostream& out, const Eigen::MatrixXd& m) {
  for (const double v : upperTriangle(m)) out << ' ' << v;
}

}  // namespace osm_graph_slam
