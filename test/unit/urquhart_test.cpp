// Geometric hierarchy (landmarks/geometric_hierarchy.h) and its matching
// (landmarks/hierarchy_matching.h): Delaunay + Urquhart graph of known point sets, descriptor
// invariance, and transform recovery under landmark dropout and noise.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <set>

#include "osm_graph_slam/landmarks/geometric_hierarchy.h"
#include "osm_graph_slam/landmarks/hierarchy_matching.h"
#include "osm_graph_slam/landmarks/landmark_place_recognizer.h"

using namespace osm_graph_slam;

namespace {

/// Poisson-disc-like forest: jittered grid (the seed's Bridson sampling + Gaussian jitter has
/// the same near-regular character).
std::vector<Eigen::Vector2d> jitteredForest(double half_size, double spacing, double jitter,
                                            uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, jitter);
  std::vector<Eigen::Vector2d> pts;
  for (double x = -half_size; x <= half_size; x += spacing)
    for (double y = -half_size; y <= half_size; y += spacing)
      pts.emplace_back(x + n(rng), y + n(rng));
  return pts;
}

std::set<std::pair<int, int>> edgeSet(const GeometricHierarchy& h) {
  return std::set<std::pair<int, int>>(h.urquhart_edges.begin(), h.urquhart_edges.end());
}

}  // namespace

// A square with its centre: 4 Delaunay triangles, each dropping its hull side (the longest, 1.0
// against 0.707): the Urquhart graph is the 4 spokes and there are 4 single-triangle polygons.
TEST(Urquhart, SquareWithCentre) {
  const std::vector<Eigen::Vector2d> pts = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5, 0.5}};
  const GeometricHierarchy h = buildGeometricHierarchy(pts, GeometricHierarchyParams());
  ASSERT_EQ(h.triangles.size(), 4u);
  const std::set<std::pair<int, int>> expected = {{0, 4}, {1, 4}, {2, 4}, {3, 4}};
  EXPECT_EQ(edgeSet(h), expected);
  EXPECT_EQ(h.polygons.size(), 4u);
  for (const auto& p : h.polygons) EXPECT_EQ(p.vertices.size(), 3u);
}

// A regular hexagon ring (radius 1) around a point pushed off-centre: the hand-derived Delaunay
// triangulation and Urquhart graph. Points: 0..5 hexagon at 60 deg steps, 6 = (0.3, 0).
// Spokes to 6: |6-0| = 0.7, |6-1| = |6-5| = 0.889, |6-2| = |6-4| = 1.148, |6-3| = 1.3.
// Triangles (6,i,i+1); hexagon sides are 1. Longest edges: (6,0,1): side 1-6 0.889 < 1 -> hull
// side 0-1 (1.0) dropped; (6,1,2): spoke 2-6 (1.148) dropped; (6,2,3): spoke 3-6 (1.3);
// (6,3,4): spoke 3-6; (6,4,5): spoke 4-6 (1.148); (6,5,0): hull side 5-0 (1.0).
TEST(Urquhart, HexagonWithOffCentrePoint) {
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i < 6; ++i) pts.emplace_back(std::cos(i * M_PI / 3), std::sin(i * M_PI / 3));
  pts.emplace_back(0.3, 0.0);
  const GeometricHierarchy h = buildGeometricHierarchy(pts, GeometricHierarchyParams());
  ASSERT_EQ(h.triangles.size(), 6u);
  const std::set<std::pair<int, int>> expected = {{1, 2}, {2, 3}, {3, 4}, {4, 5},
                                                  {0, 6}, {1, 6}, {5, 6}};
  EXPECT_EQ(edgeSet(h), expected);
  // Polygons: (6,0,1) alone, (6,5,0) alone, and (6,1,2)+(6,2,3)+(6,3,4)+(6,4,5) merged into the
  // hexagon-side polygon 6-1-2-3-4-5.
  ASSERT_EQ(h.polygons.size(), 3u);
  std::vector<size_t> sizes;
  for (const auto& p : h.polygons) sizes.push_back(p.vertices.size());
  std::sort(sizes.begin(), sizes.end());
  EXPECT_EQ(sizes, (std::vector<size_t>{3, 3, 6}));
  for (const auto& p : h.polygons) {
    if (p.vertices.size() != 6) continue;
    EXPECT_EQ(p.triangles.size(), 4u);
    std::vector<int> v = p.vertices;
    std::rotate(v.begin(), std::find(v.begin(), v.end(), 6), v.end());
    EXPECT_EQ(v, (std::vector<int>{6, 1, 2, 3, 4, 5}));  // counter-clockwise from 6
  }
}

TEST(Urquhart, DelaunayHandlesDegenerateInput) {
  EXPECT_TRUE(delaunayTriangles({}).empty());
  EXPECT_TRUE(delaunayTriangles({{0, 0}, {1, 1}}).empty());
  EXPECT_TRUE(delaunayTriangles({{0, 0}, {1, 1}, {2, 2}, {3, 3}}).empty());  // collinear
  const double nan = std::nan("");
  const auto t = delaunayTriangles({{0, 0}, {1, 0}, {nan, 0}, {0, 1}, {0, 1}});  // NaN, duplicate
  ASSERT_EQ(t.size(), 1u);
  std::array<int, 3> s = t[0];
  std::sort(s.begin(), s.end());
  EXPECT_EQ(s, (std::array<int, 3>{0, 1, 3}));
}

// Euler: a triangulation of n points with h on the convex hull has 2n - 2 - h triangles.
TEST(Urquhart, DelaunayTriangleCountOfARandomForest) {
  const auto pts = jitteredForest(30.0, 5.0, 1.5, 3);
  const auto tris = delaunayTriangles(pts);
  const int n = int(pts.size());
  // Empty circumcircle property on every triangle.
  int violations = 0;
  for (const auto& t : tris) {
    const Eigen::Vector2d a = pts[t[0]], b = pts[t[1]], c = pts[t[2]];
    const double d =
        2 * (a.x() * (b.y() - c.y()) + b.x() * (c.y() - a.y()) + c.x() * (a.y() - b.y()));
    const Eigen::Vector2d o((a.squaredNorm() * (b.y() - c.y()) + b.squaredNorm() * (c.y() - a.y()) +
                             c.squaredNorm() * (a.y() - b.y())) /
                                d,
                            (a.squaredNorm() * (c.x() - b.x()) + b.squaredNorm() * (a.x() - c.x()) +
                             c.squaredNorm() * (b.x() - a.x())) /
                                d);
    const double r = (a - o).norm();
    for (int i = 0; i < n; ++i)
      if (i != t[0] && i != t[1] && i != t[2] && (pts[i] - o).norm() < r - 1e-4) ++violations;
  }
  EXPECT_EQ(violations, 0);
  EXPECT_GE(int(tris.size()), 2 * n - 2 - 4 * 13 - 8);  // hull of a 13x13 jittered grid
  EXPECT_LE(int(tris.size()), 2 * n - 5);
  // Urquhart graph of a Delaunay triangulation stays connected (it contains the MST).
  const GeometricHierarchy h = buildGeometricHierarchy(pts, GeometricHierarchyParams());
  std::vector<int> comp(n);
  for (int i = 0; i < n; ++i) comp[i] = i;
  std::function<int(int)> find = [&](int x) { return comp[x] == x ? x : comp[x] = find(comp[x]); };
  for (const auto& [a, b] : h.urquhart_edges) comp[find(a)] = find(b);
  std::set<int> roots;
  for (int i = 0; i < n; ++i) roots.insert(find(i));
  EXPECT_EQ(roots.size(), 1u);
  // Every triangle belongs to exactly one polygon.
  size_t tri_in_polygons = 0;
  for (const auto& p : h.polygons) tri_in_polygons += p.triangles.size();
  EXPECT_EQ(tri_in_polygons, h.triangles.size());
}

TEST(PolygonDescriptor, InvariantToRotationTranslationAndStartVertex) {
  const std::vector<Eigen::Vector2d> ring = {
      {0, 0}, {6.0, -1.0}, {9.0, 3.5}, {4.0, 7.0}, {-1.5, 4.0}};
  const GeometricHierarchyParams params;
  const Eigen::VectorXf d0 = polygonDescriptor(ring, params);
  ASSERT_EQ(d0.size(), params.descriptor_harmonics);
  EXPECT_GT(d0[0], 3.0f);  // mean centroid distance of a ~10 m polygon
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.rotate(Eigen::Rotation2Dd(2.1));
  T.pretranslate(Eigen::Vector2d(153.0, -87.0));
  for (int start = 0; start < int(ring.size()); ++start) {
    std::vector<Eigen::Vector2d> moved;
    for (size_t i = 0; i < ring.size(); ++i) moved.push_back(T * ring[(start + i) % ring.size()]);
    const Eigen::VectorXf d = polygonDescriptor(moved, params);
    EXPECT_LT((d - d0).norm(), 0.01f) << "start vertex " << start;
  }
  // A different polygon is far away in descriptor space.
  std::vector<Eigen::Vector2d> other = ring;
  other[2] = Eigen::Vector2d(12.0, 1.0);
  EXPECT_GT((polygonDescriptor(other, params) - d0).norm(), 0.3f);
  // Scale is not invariant (LiDAR has none): a 10 % larger polygon differs.
  std::vector<Eigen::Vector2d> larger;
  for (const auto& p : ring) larger.push_back(1.1 * p);
  EXPECT_GT((polygonDescriptor(larger, params) - d0).norm(), 0.2f);
}

TEST(PolygonDescriptor, HierarchyDescriptorsSurviveARigidMotion) {
  const auto pts = jitteredForest(25.0, 5.0, 1.5, 7);
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.rotate(Eigen::Rotation2Dd(-0.8));
  T.pretranslate(Eigen::Vector2d(-20.0, 44.0));
  std::vector<Eigen::Vector2d> moved;
  for (const auto& p : pts) moved.push_back(T * p);
  const GeometricHierarchyParams params;
  const GeometricHierarchy a = buildGeometricHierarchy(pts, params);
  const GeometricHierarchy b = buildGeometricHierarchy(moved, params);
  ASSERT_EQ(a.polygons.size(), b.polygons.size());
  ASSERT_GT(a.polygons.size(), 20u);
  // Same polygons (as vertex sets), same descriptors, whatever vertex the boundary starts at.
  int compared = 0;
  for (const auto& pa : a.polygons) {
    std::vector<int> va = pa.vertices;
    std::sort(va.begin(), va.end());
    for (const auto& pb : b.polygons) {
      std::vector<int> vb = pb.vertices;
      std::sort(vb.begin(), vb.end());
      if (va != vb) continue;
      EXPECT_LT((pa.descriptor - pb.descriptor).norm(), 0.01f);
      ++compared;
    }
  }
  EXPECT_EQ(compared, int(a.polygons.size()));
}

// The acceptance test: a local view of a forest matched against a map with 30 % of
// the landmarks dropped (independently on both sides) and 0.2 m noise recovers the transform.
TEST(HierarchyMatching, RecoversTransformWith30PercentDropoutAnd20cmNoise) {
  int recovered = 0;
  const int trials = 10;
  for (int trial = 0; trial < trials; ++trial) {
    std::mt19937 rng(100 + trial);
    std::normal_distribution<double> noise(0.0, 0.2);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const auto forest = jitteredForest(35.0, 5.0, 1.5, 200 + trial);  // intermediate density
    Eigen::Isometry2d T_true = Eigen::Isometry2d::Identity();         // p_map = T_true * p_local
    T_true.rotate(Eigen::Rotation2Dd(u(rng) * 2 * M_PI - M_PI));
    T_true.pretranslate(Eigen::Vector2d(u(rng) * 10 - 5, u(rng) * 10 - 5));
    const Eigen::Isometry2d T_inv = T_true.inverse();
    std::vector<Eigen::Vector2d> map_pts, local_pts;
    for (const auto& p : forest) {
      if (u(rng) > 0.3) map_pts.push_back(p + Eigen::Vector2d(noise(rng), noise(rng)));
      const Eigen::Vector2d l = T_inv * p;
      if (l.norm() < 25.0 && u(rng) > 0.3)
        local_pts.push_back(l + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    const GeometricHierarchyParams hp;
    const GeometricHierarchy local = buildGeometricHierarchy(local_pts, hp);
    const GeometricHierarchy map = buildGeometricHierarchy(map_pts, hp);
    const RigidMatch m = matchLandmarkHierarchies(local, map, HierarchyMatchParams());
    if (!m.accepted) continue;
    const double dt = (m.transform.translation() - T_true.translation()).norm();
    const double dyaw = std::abs(
        Eigen::Rotation2Dd(m.transform.linear().transpose() * T_true.linear()).smallestAngle());
    EXPECT_LT(dt, 0.25) << "trial " << trial;
    EXPECT_LT(dyaw, 0.015) << "trial " << trial;
    EXPECT_GE(m.inliers, 20);
    if (dt < 0.25 && dyaw < 0.015) ++recovered;
  }
  EXPECT_GE(recovered, 9) << "of " << trials;
}

// Two different forests of the same density must not match (the precision side).
TEST(HierarchyMatching, RejectsADifferentForest) {
  int accepted = 0;
  for (int trial = 0; trial < 10; ++trial) {
    const auto a = jitteredForest(25.0, 5.0, 1.5, 300 + trial);
    const auto b = jitteredForest(25.0, 5.0, 1.5, 400 + trial);
    const GeometricHierarchyParams hp;
    const RigidMatch m = matchLandmarkHierarchies(
        buildGeometricHierarchy(a, hp), buildGeometricHierarchy(b, hp), HierarchyMatchParams());
    accepted += m.accepted;
  }
  EXPECT_EQ(accepted, 0);
}

TEST(LandmarkPlaceRecognizer, FindsTheRightKeyframeAmongMany) {
  // Keyframes every 10 m along a line through a 400 m forest; queries from other positions and
  // headings near keyframes 5, 17 and 30 must come back to them.
  const auto forest = jitteredForest(200.0, 5.0, 1.5, 11);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto view = [&](const Eigen::Vector2d& at, double yaw) {
    Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
    T.rotate(Eigen::Rotation2Dd(yaw));
    T.pretranslate(at);
    const Eigen::Isometry2d inv = T.inverse();
    std::vector<Eigen::Vector2d> out;
    for (const auto& p : forest) {
      const Eigen::Vector2d l = inv * p;
      if (l.norm() < 30.0 && u(rng) > 0.1)
        out.push_back(l + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    return out;
  };
  LandmarkPlaceRecognizer db;
  for (int k = 0; k < 36; ++k) db.add(view(Eigen::Vector2d(-175.0 + 10.0 * k, 3.0), 0.0));
  EXPECT_GT(db.numIndexedPolygons(), 36u * 10u);
  for (int k : {5, 17, 30}) {
    const Eigen::Vector2d at(-175.0 + 10.0 * k + 2.0, 1.0);
    const LandmarkQueryResult r = db.query(view(at, 2.5), db.size());
    ASSERT_TRUE(r.found) << "near keyframe " << k;
    // Keyframes 10 m apart with a 30 m range overlap: any keyframe seeing the same trees is
    // right if the transform agrees. p_kf = T * p_query, keyframes have yaw 0: the query origin
    // is at kf + T.translation().
    EXPECT_LE(std::abs(r.keyframe - k), 5);
    const Eigen::Vector2d kf(-175.0 + 10.0 * r.keyframe, 3.0);
    EXPECT_LT((kf + r.match.transform.translation() - at).norm(), 0.4) << "near keyframe " << k;
    EXPECT_NEAR(Eigen::Rotation2Dd(r.match.transform.linear()).smallestAngle(), 2.5, 0.02);
  }
  // Excluding the keyframes from 17 on, a query at 30 finds nothing (no false match).
  const LandmarkQueryResult none = db.query(view(Eigen::Vector2d(125.0, 3.0), 1.0), 17);
  EXPECT_FALSE(none.found);
  // Bad input: no landmarks, too few.
  EXPECT_FALSE(db.query(std::vector<Eigen::Vector2d>{}, db.size()).found);
  EXPECT_FALSE(db.query(std::vector<Eigen::Vector2d>{{1, 1}, {2, 2}}, db.size()).found);
}
