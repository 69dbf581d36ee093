#pragma once
// Geometric hierarchy of 2D landmark positions (GeoSLAM thesis §3.2.1-3.2.2, after Nardari et
// al., "Place recognition in forests with Urquhart tessellations"): Delaunay triangulation ->
// Urquhart graph (the longest edge of every triangle dropped) -> polygons (the triangles merged
// across the dropped edges), each polygon and triangle with a shape descriptor invariant to
// rotation, translation and the vertex the boundary starts at.
//
// Delaunay: OpenCV's cv::Subdiv2D (OpenCV is already a dependency; see doc/landmarks.md for why
// not CGAL or Qhull).
#include <Eigen/Core>
#include <array>
#include <utility>
#include <vector>

namespace osm_graph_slam {

struct GeometricHierarchyParams {
  /// Points sampled at equal arc length along a polygon boundary for its descriptor. The seed
  /// uses s = 0.05 (20 samples); 128 makes the DFT magnitudes start-vertex invariant to ~1 mm
  /// (a start vertex is a sub-sample shift of the sampled signal, and corners alias less).
  int descriptor_samples = 128;
  /// DFT magnitudes kept (harmonics 0..n-1, in metres: |X_k| / samples). Harmonic 0 is the mean
  /// centroid distance (the size), the next ones the shape.
  int descriptor_harmonics = 8;
  /// Delaunay edges longer than this are not used (triangles across empty areas, e.g. between
  /// the two sides of a clearing, change with every missed landmark) [m].
  double max_edge_length = 30.0;
};

/// A Delaunay triangle: landmark indices counter-clockwise; side i joins v[i] and v[(i+1)%3].
struct HierarchyTriangle {
  std::array<int, 3> v{{0, 0, 0}};
  std::array<double, 3> side{{0, 0, 0}};
  int longest = 0;  ///< index of the longest side
  /// Sides sorted longest first: the triangle's descriptor (rotation/translation/start
  /// invariant; no mirror images in LiDAR data, so the cyclic order is kept for matching).
  std::array<double, 3> sorted_sides{{0, 0, 0}};
};

struct UrquhartPolygon {
  std::vector<int> vertices;   ///< boundary landmark indices, counter-clockwise
  std::vector<int> triangles;  ///< indices into GeometricHierarchy::triangles
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  ///< area centroid
  double perimeter = 0.0;
  Eigen::VectorXf descriptor;  ///< descriptor_harmonics DFT magnitudes [m]
};

/// The three tiers: polygons -> triangles -> edges/vertices (the landmarks).
struct GeometricHierarchy {
  std::vector<Eigen::Vector2d> points;
  std::vector<HierarchyTriangle> triangles;         ///< every Delaunay triangle used
  std::vector<std::pair<int, int>> urquhart_edges;  ///< (a < b), sorted
  std::vector<UrquhartPolygon> polygons;
};

/// Delaunay triangles of the points (indices, counter-clockwise). Duplicate points (closer than
/// 1 mm) are triangulated once (the first index); fewer than 3 distinct points or all collinear
/// gives no triangle. Non-finite points are skipped.
std::vector<std::array<int, 3>> delaunayTriangles(const std::vector<Eigen::Vector2d>& points);

/// Descriptor of a closed boundary (vertices in order, first not repeated): the DFT magnitudes
/// of the centroid distance sampled at equal arc length from ring[0]. Empty if degenerate.
Eigen::VectorXf polygonDescriptor(const std::vector<Eigen::Vector2d>& ring,
                                  const GeometricHierarchyParams& params);

/// Builds the whole hierarchy (Delaunay, Urquhart graph, polygons with descriptors).
GeometricHierarchy buildGeometricHierarchy(const std::vector<Eigen::Vector2d>& points,
                                           const GeometricHierarchyParams& params);

}  // namespace osm_graph_slam
