#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"

#include <algorithm>
#include <chrono>
#include <map>

#include "osm_graph_slam/common/dynamic_kd_index.h"

namespace osm_graph_slam {

namespace {
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}
}  // namespace

LandmarkPlaceRecognizer::LandmarkPlaceRecognizer(const LandmarkPlaceRecognitionParams& params)
    : params_(params),
      index_(std::make_unique<DynamicKdIndex>(std::max(1, params.hierarchy.descriptor_harmonics))) {
}

LandmarkPlaceRecognizer::~LandmarkPlaceRecognizer() = default;

size_t LandmarkPlaceRecognizer::add(const std::vector<Eigen::Vector2d>& landmarks) {
  if (int(landmarks.size()) < params_.min_landmarks) return add(GeometricHierarchy());
  return add(buildGeometricHierarchy(landmarks, params_.hierarchy));
}

size_t LandmarkPlaceRecognizer::add(GeometricHierarchy hierarchy) {
  const size_t id = keyframes_.size();
  first_polygon_.push_back(owners_.size());
  for (size_t p = 0; p < hierarchy.polygons.size(); ++p) {
    const UrquhartPolygon& poly = hierarchy.polygons[p];
    if (int(poly.vertices.size()) < params_.min_indexed_vertices) continue;
    if (poly.descriptor.size() != index_->dimension()) continue;
    if (index_->add(poly.descriptor.data())) owners_.push_back({int(id), int(p)});
  }
  keyframes_.push_back(std::move(hierarchy));
  return id;
}

LandmarkQueryResult LandmarkPlaceRecognizer::query(const std::vector<Eigen::Vector2d>& landmarks,
                                                   size_t keyframe_limit) const {
  const auto t0 = Clock::now();
  GeometricHierarchy h;
  if (int(landmarks.size()) >= params_.min_landmarks)
    h = buildGeometricHierarchy(landmarks, params_.hierarchy);
  const double hierarchy_ms = msSince(t0);
  LandmarkQueryResult r = query(h, keyframe_limit);
  r.hierarchy_ms = hierarchy_ms;
  return r;
}

LandmarkQueryResult LandmarkPlaceRecognizer::query(const GeometricHierarchy& h,
                                                   size_t keyframe_limit) const {
  LandmarkQueryResult result;
  keyframe_limit = std::min(keyframe_limit, keyframes_.size());
  if (keyframe_limit == 0 || h.polygons.empty()) return result;
  const size_t index_limit =
      keyframe_limit < first_polygon_.size() ? first_polygon_[keyframe_limit] : owners_.size();
  if (index_limit == 0) return result;

  // Retrieval: each query polygon votes once for every keyframe owning one of its nearest
  // descriptors within tau (and within Delta_N vertices).
  const auto t1 = Clock::now();
  const float tau2 = float(params_.match.polygon_max_descriptor_distance *
                           params_.match.polygon_max_descriptor_distance);
  std::map<int, int> votes;
  for (size_t p = 0; p < h.polygons.size(); ++p) {
    const UrquhartPolygon& poly = h.polygons[p];
    if (int(poly.vertices.size()) < params_.min_indexed_vertices) continue;
    if (poly.descriptor.size() != index_->dimension()) continue;
    std::vector<int> voted;
    for (const auto& [idx, d2] :
         index_->knn(poly.descriptor.data(), size_t(params_.polygon_neighbours), index_limit)) {
      if (d2 > tau2) break;
      const Owner& o = owners_[idx];
      const auto& other = keyframes_[o.keyframe].polygons[o.polygon];
      if (std::abs(int(other.vertices.size()) - int(poly.vertices.size())) >
          params_.match.polygon_max_vertex_difference)
        continue;
      if (std::find(voted.begin(), voted.end(), o.keyframe) == voted.end()) {
        voted.push_back(o.keyframe);
        ++votes[o.keyframe];
      }
    }
  }
  std::vector<std::pair<int, int>> ranked;  // (votes, keyframe)
  for (const auto& [kf, v] : votes)
    if (v >= params_.min_votes) ranked.push_back({v, kf});
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  if (int(ranked.size()) > params_.max_candidates) ranked.resize(params_.max_candidates);
  result.retrieval_ms = msSince(t1);

  // Verification: full hierarchical matching (every polygon pair, triangles included: a
  // descriptor comparison costs nanoseconds) + RANSAC against the candidate's hierarchy.
  const auto t2 = Clock::now();
  for (const auto& [v, kf] : ranked) {
    ++result.candidates_verified;
    const RigidMatch m = matchLandmarkHierarchies(h, keyframes_[kf], params_.match);
    if (!m.accepted) continue;
    if (!result.found || m.inliers > result.match.inliers) {
      result.found = true;
      result.keyframe = kf;
      result.match = m;
      result.votes = v;
    }
  }
  result.verification_ms = msSince(t2);
  return result;
}

}  // namespace osm_graph_slam
