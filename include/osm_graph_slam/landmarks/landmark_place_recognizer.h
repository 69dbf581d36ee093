#pragma once
// Place recognition from landmark geometry alone (GeoSLAM): every stored keyframe keeps its
// geometric hierarchy, and the descriptors of all its polygons go into one KD-tree (like the
// seed's global hierarchy, the query cost grows with the number of polygons only through a
// tree search). A query's polygons vote for the keyframes owning their nearest descriptors;
// the best-voted keyframes are verified by hierarchical matching + RANSAC.
#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <vector>

#include "osm_graph_slam/landmarks/geometric_hierarchy.h"
#include "osm_graph_slam/landmarks/hierarchy_matching.h"

namespace osm_graph_slam {

class DynamicKdIndex;

struct LandmarkPlaceRecognitionParams {
  GeometricHierarchyParams hierarchy;
  HierarchyMatchParams match;
  int polygon_neighbours = 24;  ///< nearest stored descriptors looked up per query polygon
  int max_candidates = 4;       ///< best-voted keyframes verified
  int min_votes = 2;            ///< polygons that must point at a keyframe to verify it
  int min_landmarks = 6;        ///< fewer landmarks: nothing stored / nothing queried
  /// Polygons of fewer vertices are not indexed: triangles are everywhere alike in a forest
  /// and would crowd the neighbour lists (they still match inside verified polygons).
  int min_indexed_vertices = 4;
};

struct LandmarkQueryResult {
  bool found = false;
  int keyframe = -1;  ///< index of the matched stored keyframe
  RigidMatch match;   ///< p_keyframe = match.transform * p_query
  int votes = 0;
  int candidates_verified = 0;
  double hierarchy_ms = 0.0, retrieval_ms = 0.0, verification_ms = 0.0;
};

class LandmarkPlaceRecognizer {
 public:
  explicit LandmarkPlaceRecognizer(const LandmarkPlaceRecognitionParams& params = {});
  ~LandmarkPlaceRecognizer();
  LandmarkPlaceRecognizer(const LandmarkPlaceRecognizer&) = delete;
  LandmarkPlaceRecognizer& operator=(const LandmarkPlaceRecognizer&) = delete;

  const LandmarkPlaceRecognitionParams& params() const { return params_; }
  size_t size() const { return keyframes_.size(); }
  size_t numIndexedPolygons() const { return owners_.size(); }
  const GeometricHierarchy& keyframe(size_t i) const { return keyframes_[i]; }

  /// Stores a keyframe's landmarks (2D, keyframe frame); returns its index. A keyframe with
  /// too few landmarks is stored empty (it keeps the numbering) and is never matched.
  size_t add(const std::vector<Eigen::Vector2d>& landmarks);
  size_t add(GeometricHierarchy hierarchy);

  /// Best matching keyframe among the first `keyframe_limit` stored ones (e.g. all but the
  /// recent ones for loop detection; size() for global localisation).
  LandmarkQueryResult query(const std::vector<Eigen::Vector2d>& landmarks,
                            size_t keyframe_limit) const;
  LandmarkQueryResult query(const GeometricHierarchy& hierarchy, size_t keyframe_limit) const;

 private:
  struct Owner {
    int keyframe, polygon;
  };
  LandmarkPlaceRecognitionParams params_;
  std::vector<GeometricHierarchy> keyframes_;
  std::vector<size_t> first_polygon_;  ///< per keyframe: index of its first indexed polygon
  std::vector<Owner> owners_;          ///< per indexed polygon
  std::unique_ptr<DynamicKdIndex> index_;
};

}  // namespace osm_graph_slam
