// Ground-truth-free measures of a run: wall agreement with prior and corrected outlines, the shift
// of unobserved buildings, and map sharpness (a blurred map scores worse).
#include <gtest/gtest.h>

#include <map>
#include <random>
#include <string>

#include "osm_graph_slam/eval/map_agreement.h"
#include "osm_graph_slam/osm/building_set.h"

using namespace osm_graph_slam;

namespace {

Building square(int64_t id, const Eigen::Vector2d& corner, double size) {
  Building b;
  b.id = id;
  b.outline_enu = {corner, corner + Eigen::Vector2d(size, 0), corner + Eigen::Vector2d(size, size),
                   corner + Eigen::Vector2d(0, size)};
  return b;
}

/// Points on the south wall (y = y0) of a building, heights 1.5-4.5 m, in a keyframe at the
/// origin (identity pose), with noise sigma.
PointCloudPtr wallPoints(double x0, double x1, double y0, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, static_cast<float>(sigma));
  PointCloudPtr c = std::make_shared<PointCloud>();
  for (double x = x0; x <= x1; x += 0.05)
    for (double z = 1.5; z <= 4.5; z += 0.1) {
      PointT p;
      p.x = static_cast<float>(x), p.y = static_cast<float>(y0) + n(rng),
      p.z = static_cast<float>(z);
      c->push_back(p);
    }
  return c;
}

}  // namespace

TEST(WallAgreement, CorrectedOutlineOnTheWallsAndUnobservedShift) {
  // Building 1: true south wall at y = 10; the prior puts it 1.2 m too far north, the corrected
  // outline 0.1 m. Building 2 is far from every point and moved by 0.5 m.
  const Building prior1 = square(1, {0, 11.2}, 20), corrected1 = square(1, {0, 10.1}, 20);
  const Building prior2 = square(2, {100, 100}, 10), corrected2 = square(2, {100.3, 100.4}, 10);
  const std::vector<PosedCloud> kfs = {
      {Eigen::Isometry3d::Identity(), wallPoints(2, 18, 10, 0.02, 1)}};
  const WallAgreement w = evaluateWallAgreement(kfs, {prior1, prior2}, {corrected1, corrected2});
  ASSERT_EQ(w.observed.size(), 1u);
  EXPECT_EQ(w.observed[0].id, 1);
  EXPECT_GT(w.points, 50u);
  EXPECT_NEAR(w.observed[0].prior_median, 1.2, 0.03);
  EXPECT_NEAR(w.observed[0].corrected_median, 0.1, 0.03);
  EXPECT_NEAR(w.observed[0].shift, 1.1, 1e-9);
  EXPECT_NEAR(w.prior_median, 1.2, 0.03);
  EXPECT_NEAR(w.corrected_median, 0.1, 0.03);
  EXPECT_EQ(w.unobserved, 1u);
  EXPECT_NEAR(w.max_unobserved_shift, 0.5, 1e-9);
  EXPECT_EQ(w.max_unobserved_shift_id, 2);

  // With the back-end's OSM datum (the extract's common offset), what the unobserved building
  // moved on its own: here it moved exactly with a datum of (0.3, 0.4), so nothing; a datum
  // rotated about the origin moves building 2 (at 100 m) by 1.4 m more.
  WallAgreementOptions with_datum;
  with_datum.datum = Eigen::Vector3d(0.3, 0.4, 0.0);
  const WallAgreement wd =
      evaluateWallAgreement(kfs, {prior1, prior2}, {corrected1, corrected2}, with_datum);
  EXPECT_NEAR(wd.max_unobserved_shift, 0.5, 1e-9);
  EXPECT_NEAR(wd.max_unobserved_shift_after_datum, 0.0, 1e-9);
  with_datum.datum = Eigen::Vector3d(0.3, 0.4, 0.01);
  EXPECT_GT(evaluateWallAgreement(kfs, {prior1, prior2}, {corrected1, corrected2}, with_datum)
                .max_unobserved_shift_after_datum,
            1.0);
  EXPECT_DOUBLE_EQ(w.max_unobserved_shift_after_datum, -1.0) << "no datum given";

  // Points outside the height band are not walls (a car at 0.5 m, a roof at 8 m).
  WallAgreementOptions high;
  high.min_z = 5.0;
  high.max_z = 9.0;
  EXPECT_TRUE(evaluateWallAgreement(kfs, {prior1}, {corrected1}, high).observed.empty());
}

TEST(WallAgreement, ARoofOnOpenSidesIsNotMeasuredByTheWallsBesideIt) {
  // The real drive's tram shelter (building=roof): a fence runs 1.2 m beside the prior outline
  // and 3.5 m from the corrected one, which lies on the shelter's own points (its roof, seen
  // from below). As a building with walls the fence made the correction look 3 m wrong.
  Building prior = square(5, {0, 11.2}, 4), corrected = square(5, {0, 2.5}, 4);
  PointCloudPtr points = wallPoints(-1, 5, 10, 0.02, 2);  // the fence
  for (double x = 0.5; x < 3.6; x += 0.25)
    for (double y = 3.0; y < 6.0; y += 0.25) {
      PointT p;
      p.x = static_cast<float>(x), p.y = static_cast<float>(y), p.z = 2.8f;
      points->push_back(p);
    }
  const std::vector<PosedCloud> kfs = {{Eigen::Isometry3d::Identity(), points}};
  const WallAgreement as_walls = evaluateWallAgreement(kfs, {prior}, {corrected});
  ASSERT_EQ(as_walls.observed.size(), 1u);
  EXPECT_GT(as_walls.corrected_median, as_walls.prior_median + 1.0);

  prior.tags["building"] = corrected.tags["building"] = "roof";
  const WallAgreement w = evaluateWallAgreement(kfs, {prior}, {corrected});
  EXPECT_TRUE(w.observed.empty());
  EXPECT_EQ(w.unobserved, 0u);
  ASSERT_EQ(w.roof_only.size(), 1u);
  EXPECT_EQ(w.roof_only[0].id, 5);
  EXPECT_EQ(w.roof_only[0].inside_prior, 0u);
  EXPECT_GT(w.roof_only[0].inside_corrected, 100u);
  EXPECT_NEAR(w.roof_only[0].shift, 8.7, 1e-9);

  for (const auto& [key, value] :
       std::map<std::string, std::string>{{"building", "carport"}, {"building:walls", "no"}}) {
    Building b = square(6, {0, 0}, 4);
    b.tags[key] = value;
    EXPECT_TRUE(isRoofOnly(b)) << key << "=" << value;
  }
  Building house = square(7, {0, 0}, 4);
  house.tags["building"] = "yes";
  house.tags["amenity"] = "shelter";  // a shelter with walls
  EXPECT_FALSE(isRoofOnly(house));
}

TEST(MapSharpness, ABlurredMapScoresWorse) {
  const auto wall = wallPoints(0, 10, 5, 0.01, 2);
  Eigen::Isometry3d off = Eigen::Isometry3d::Identity();
  off.translation() << 0.0, 0.08, 0.0;  // the same wall seen from a pose 8 cm off
  const MapSharpness sharp = evaluateMapSharpness(
      {{Eigen::Isometry3d::Identity(), wall}, {Eigen::Isometry3d::Identity(), wall}});
  const MapSharpness blurred =
      evaluateMapSharpness({{Eigen::Isometry3d::Identity(), wall}, {off, wall}});
  EXPECT_GT(sharp.points, 100u);
  EXPECT_LT(sharp.mean_plane_variance, 2e-4);
  EXPECT_GT(blurred.mean_plane_variance, 2.0 * sharp.mean_plane_variance);
  EXPECT_EQ(evaluateMapSharpness({}).points, 0u);
}
