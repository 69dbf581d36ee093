// The global landmark map (GeoSLAM §4.3, doc/landmarks.md §8): discovery merges what several
// keyframes agree on and nothing else; tiles find a viewpoint no keyframe had.
#include <gtest/gtest.h>

#include <iostream>
#include <random>

#include "osm_graph_slam/landmarks/landmark_map.h"

namespace osm_graph_slam {
namespace {

constexpr double kNoise = 0.15;  ///< [m] per axis, each observation

/// Trunks on a jittered 7 m grid over 100 x 60 m (no two closer than ~3 m).
std::vector<Eigen::Vector2d> trunks() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-1.5, 1.5);
  std::vector<Eigen::Vector2d> out;
  for (double x = 0.0; x <= 100.0; x += 7.0)
    for (double y = -30.0; y <= 30.0; y += 7.0) out.emplace_back(x + jitter(rng), y + jitter(rng));
  return out;
}

/// What a keyframe at pose sees: trunks within 25 m, 90 % detected, noisy, plus 3 clutter points.
std::vector<Eigen::Vector2d> observe(const std::vector<Eigen::Vector2d>& world, const Pose2& pose,
                                     std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, kNoise);
  std::uniform_real_distribution<double> u(0.0, 1.0), clutter(-20.0, 20.0);
  std::vector<Eigen::Vector2d> out;
  const Pose2 inv = pose.inverse();
  for (const Eigen::Vector2d& t : world) {
    if ((t - pose.translation()).norm() > 25.0 || u(rng) > 0.9) continue;
    out.push_back(inv.transform(t) + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  for (int i = 0; i < 3; ++i) out.emplace_back(clutter(rng), clutter(rng));
  return out;
}

struct MappedDrive {
  std::vector<KeyframeLandmarks> keyframes;
  std::vector<Eigen::Vector2d> path;
};

MappedDrive drive(const std::vector<Eigen::Vector2d>& world) {
  std::mt19937 rng(9);
  MappedDrive d;
  for (double x = 5.0; x <= 95.0; x += 4.0) {
    KeyframeLandmarks& k = d.keyframes.emplace_back();
    k.pose = Pose2(x, 0.5, 0.02 * x);
    k.landmarks = observe(world, k.pose, rng);
    d.path.push_back(k.pose.translation());
  }
  return d;
}

double nearestDistance(const std::vector<Eigen::Vector2d>& points, const Eigen::Vector2d& p) {
  double best = 1e9;
  for (const auto& q : points) best = std::min(best, (q - p).norm());
  return best;
}

TEST(LandmarkMap, DiscoveryKeepsWhatKeyframesAgreeOn) {
  const std::vector<Eigen::Vector2d> world = trunks();
  const MappedDrive d = drive(world);
  const LandmarkMapParams params;  // k = 3, delta = 0.6 m
  const std::vector<MapLandmark> map = discoverLandmarks(d.keyframes, params);
  double mean_error = 0.0;
  int clutter = 0;
  for (const MapLandmark& m : map) {
    const double e = nearestDistance(world, m.position);
    clutter += e > 1.0;
    mean_error += e / map.size();
    EXPECT_GE(m.observations, params.min_observations);
    EXPECT_LT(m.spread, 0.5);
  }
  std::cout << map.size() << " landmarks, mean error " << mean_error << " m, " << clutter
            << " from clutter\n";
  EXPECT_EQ(clutter, 0) << "a clutter point of one keyframe never becomes a landmark";
  // Averaging k >= 3 observations of sigma 0.15 m per axis: well under one observation's error.
  EXPECT_LT(mean_error, 0.15);
  // Every trunk within 12 m of the path is seen by many keyframes and must be mapped.
  int near_path = 0, mapped = 0;
  std::vector<Eigen::Vector2d> positions;
  for (const MapLandmark& m : map) positions.push_back(m.position);
  for (const Eigen::Vector2d& t : world) {
    if (std::abs(t.y()) > 12.0 || t.x() < 10.0 || t.x() > 90.0) continue;
    ++near_path;
    mapped += nearestDistance(positions, t) < 0.5;
  }
  EXPECT_EQ(mapped, near_path);

  LandmarkMapParams single = params;
  single.min_observations = 1;
  EXPECT_GT(discoverLandmarks(d.keyframes, single).size(), map.size() + 60)
      << "k = 1 keeps every keyframe's clutter";
}

TEST(LandmarkMap, TilesLocaliseAViewpointOffThePath) {
  const std::vector<Eigen::Vector2d> world = trunks();
  const MappedDrive d = drive(world);
  const LandmarkMapParams params;
  const LandmarkMapRecognizer recognizer(discoverLandmarks(d.keyframes, params), d.path, params,
                                         LandmarkPlaceRecognitionParams());
  EXPECT_GE(recognizer.tileCentres().size(), 8u);
  std::mt19937 rng(77);
  int right = 0, wrong = 0;
  for (double x = 12.0; x <= 88.0; x += 8.0) {
    const Pose2 truth(x, 9.0, 2.5);  // 8.5 m beside the path, heading turned back
    const auto match = recognizer.query(observe(world, truth, rng));
    if (!match) continue;
    const Pose2 err = truth.inverse() * match->pose;
    (err.translation().norm() < 0.3 && std::abs(err.theta) < 0.02 ? right : wrong)++;
  }
  std::cout << right << " right, " << wrong << " wrong of 10\n";
  EXPECT_EQ(wrong, 0);
  EXPECT_GE(right, 9) << "of 10";
}

}  // namespace
}  // namespace osm_graph_slam
