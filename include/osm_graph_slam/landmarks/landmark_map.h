#pragma once
// A global landmark map (GeoSLAM thesis §4.3): the trunks and poles seen from many keyframes of a
// mapped drive, merged into one set of map landmarks, and place recognition against it.
//
// Discovery (§4.3.4): a landmark enters the map only when `min_observations` keyframes agree on
// its position within `association_distance` (the thesis' k and δ); a single keyframe's clutter
// or a missed detection does not. Each map landmark is the mean of its observations, so it is
// more accurate than any one scan's and the map holds landmarks no single keyframe saw together.
//
// Place recognition (§4.3.2–4.3.3): one geometric hierarchy over the whole map would change with
// every landmark and grow with the map, so the map is cut into overlapping tiles (centres along
// the mapped path, `tile_spacing` apart, landmarks within `tile_radius`), each indexed like a
// keyframe in a LandmarkPlaceRecognizer. A query names a tile and the 2D transform into it.
#include <Eigen/Geometry>
#include <memory>
#include <optional>
#include <vector>

#include "osm_graph_slam/common/planar_pose.h"
#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"

namespace osm_graph_slam {

struct LandmarkMapParams {
  double association_distance = 0.6;  ///< [m] δ: observations of one landmark agree within it
  int min_observations = 3;           ///< k: keyframes that must see a landmark to map it
  double tile_radius = 35.0;          ///< [m] map landmarks indexed with a tile
  double tile_spacing = 10.0;         ///< [m] between tile centres along the mapped path
};

/// One keyframe's landmarks (2D, keyframe frame) and its planar pose in the map.
struct KeyframeLandmarks {
  Pose2 pose;
  std::vector<Eigen::Vector2d> landmarks;
};

struct MapLandmark {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  ///< map frame, mean of the observations
  int observations = 0;                                ///< keyframes that saw it
  double spread = 0.0;  ///< [m] RMS distance of the observations from the mean
};

/// Landmark discovery over keyframes in path order: each observation joins the nearest open
/// group within association_distance that this keyframe has not joined yet (a landmark is seen
/// once per keyframe), else opens one; groups with at least min_observations keyframes become
/// map landmarks. Greedy consensus instead of the thesis' k-clique: with δ below half the
/// spacing of neighbouring trunks the two agree, and this is linear in the observations.
std::vector<MapLandmark> discoverLandmarks(const std::vector<KeyframeLandmarks>& keyframes,
                                           const LandmarkMapParams& params);

struct LandmarkMapMatch {
  Pose2 pose;  ///< the query's frame in the map
  int tile = -1;
  RigidMatch match;  ///< p_tile = match.transform * p_query
};

class LandmarkMapRecognizer {
 public:
  /// Tiles along `path` (map positions in order, e.g. the keyframes') over `landmarks`.
  LandmarkMapRecognizer(std::vector<MapLandmark> landmarks,
                        const std::vector<Eigen::Vector2d>& path, const LandmarkMapParams& params,
                        const LandmarkPlaceRecognitionParams& recognition);
  ~LandmarkMapRecognizer();

  /// The best tile for a scan's landmarks (2D, scan frame), or nothing.
  std::optional<LandmarkMapMatch> query(const std::vector<Eigen::Vector2d>& landmarks) const;

  const std::vector<MapLandmark>& landmarks() const { return landmarks_; }
  const std::vector<Eigen::Vector2d>& tileCentres() const { return centres_; }

 private:
  std::vector<MapLandmark> landmarks_;
  std::vector<Eigen::Vector2d> centres_;
  std::unique_ptr<LandmarkPlaceRecognizer> recognizer_;
};

}  // namespace osm_graph_slam
