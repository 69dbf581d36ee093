#pragma once
// Hierarchical matching of two geometric hierarchies (GeoSLAM thesis §3.2.3, §4.3.3): polygons
// by descriptor (vertex counts within Delta_N, distance below tau) -> their triangles by sorted
// side lengths (a polygon pair counts when at least eta of its triangles match) -> the vertices
// of matched triangles by the cyclic side order -> landmark correspondences -> a rigid 2D
// transform by RANSAC over triangle hypotheses, scored on every landmark (nearest neighbour
// within inlier_distance), refined by least squares on the inliers.
#include <Eigen/Geometry>
#include <cstdint>
#include <utility>
#include <vector>

#include "osm_graph_slam/common/planar_pose.h"  // fitRigid2d
#include "osm_graph_slam/landmarks/geometric_hierarchy.h"

namespace osm_graph_slam {

struct HierarchyMatchParams {
  /// tau: largest polygon descriptor distance [m] (Euclidean over the DFT magnitudes).
  double polygon_max_descriptor_distance = 0.6;
  /// Delta_N: largest difference of the vertex counts of two matched polygons (seed: 3).
  int polygon_max_vertex_difference = 3;
  /// Largest norm of the difference of two triangles' sorted side lengths [m].
  double triangle_max_side_difference = 0.6;
  /// eta: fraction of a polygon pair's triangles that must match (seed: 0.5).
  double min_triangle_match_ratio = 0.5;
  /// alpha: triangle hypotheses scored at most (seed: 75 pose attempts).
  int ransac_hypotheses = 75;
  /// A transformed query landmark with a candidate landmark this close is an inlier [m]
  /// (~2.5 sigma of the seed's 0.2 m position noise on both sides).
  double inlier_distance = 0.7;
  /// gamma/mu: fewest inlier landmarks for an accepted transform.
  int min_inliers = 10;
  /// Inliers over the query landmarks that land within overlap_radius of a candidate landmark
  /// (i.e. inside the candidate's observed area): a wrong alignment of a random forest pairs
  /// only a few percent of them.
  double min_inlier_ratio = 0.35;
  double overlap_radius = 4.0;  ///< [m]
  uint32_t seed = 1;            ///< hypothesis sampling when there are more than alpha
  /// Triangle tier (beyond the seed): hypotheses also from triangles matched directly by their
  /// sorted sides, closest first, at most this many (0: polygon tier only). Landmark dropout
  /// reshapes the polygons but leaves every Delaunay triangle whose three landmarks are seen.
  int triangle_tier_hypotheses = 200;
  double triangle_tier_max_side_difference = 1.0;  ///< [m]
  /// Hough bins ordering the triangle tier: translation [m], rotation [rad]; pairs whose
  /// 3x3x3 bin neighbourhood holds fewer votes are not tried.
  double hough_translation_bin = 2.0;
  double hough_rotation_bin = 0.1;
  int hough_min_votes = 3;
  /// Query landmarks probed before a hypothesis is scored on all of them (preemptive RANSAC).
  int probe_landmarks = 16;
  /// beta: stop at a hypothesis with at least min_inliers and this inlier ratio.
  double early_exit_ratio = 0.6;
};

struct LandmarkCorrespondence {
  int query = -1, candidate = -1;
  int votes = 0;  ///< matched triangles that produced it
};

struct PolygonPair {
  int query = -1, candidate = -1;
};

/// Landmark correspondences from polygon -> triangle -> vertex matching. polygon_pairs: the
/// polygon pairs to try (e.g. from a descriptor index); null = every pair (O(Pq * Pc)).
/// triangle_pairs (optional out): matched (query, candidate) triangle indices.
std::vector<LandmarkCorrespondence> matchHierarchies(
    const GeometricHierarchy& query, const GeometricHierarchy& candidate,
    const HierarchyMatchParams& params, const std::vector<PolygonPair>* polygon_pairs = nullptr,
    std::vector<std::pair<int, int>>* triangle_pairs = nullptr, int* matched_polygons = nullptr);

struct RigidMatch {
  bool accepted = false;
  /// p_candidate = transform * p_query.
  Eigen::Isometry2d transform = Eigen::Isometry2d::Identity();
  int inliers = 0;
  int overlap = 0;  ///< query landmarks inside the candidate's area (denominator of the ratio)
  double inlier_ratio = 0.0;
  double rms = 0.0;  ///< [m] over the inliers
  int matched_polygons = 0;
  int correspondences = 0;
  std::vector<std::pair<int, int>> associations;  ///< (query, candidate) landmark indices
};

/// The whole match: hierarchical correspondences, RANSAC, refinement, acceptance tests.
RigidMatch matchLandmarkHierarchies(const GeometricHierarchy& query,
                                    const GeometricHierarchy& candidate,
                                    const HierarchyMatchParams& params,
                                    const std::vector<PolygonPair>* polygon_pairs = nullptr);

}  // namespace osm_graph_slam
