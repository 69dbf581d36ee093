// findBuildingContacts: which neighbouring outlines share a wall.
#include <gtest/gtest.h>

#include "osm_graph_slam/slam/building_contacts.h"

namespace osm_graph_slam {
namespace {

Polygon2 rectangle(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

Polygon2 clockwise(Polygon2 p) {
  return Polygon2(p.rbegin(), p.rend());
}

/// config/sim.yaml: a prior that misplaces each building on its own.
BuildingContactParams simulatedPrior() {
  BuildingContactParams p;
  p.max_distance = 2.5;
  return p;
}

TEST(BuildingContacts, RowHousesMisplacedByTheirPriorStillShareTheirWalls) {
  // Three row houses along x: the second overlaps the first by 0.8 m, the third leaves a 1.2 m
  // gap; the middle one is stored clockwise (winding must not matter).
  const std::vector<Polygon2> row = {rectangle(0, 0, 10, 12),
                                     clockwise(rectangle(9.2, 0.3, 17, 12.3)),
                                     rectangle(18.2, -0.2, 26, 11.8)};
  const auto contacts = findBuildingContacts(row, simulatedPrior());
  ASSERT_EQ(contacts.size(), 2u);
  EXPECT_EQ(contacts[0].a, 0u);
  EXPECT_EQ(contacts[0].b, 1u);
  EXPECT_NEAR(contacts[0].distance, -0.8, 1e-9) << "overlap";
  EXPECT_NEAR(contacts[0].b_normal.x(), -1.0, 1e-9) << "the second house's west wall";
  EXPECT_NEAR(contacts[0].shared_length, 11.7, 1e-9);
  EXPECT_EQ(contacts[1].a, 1u);
  EXPECT_EQ(contacts[1].b, 2u);
  EXPECT_NEAR(contacts[1].distance, 1.2, 1e-9) << "gap";
  for (const auto& end : contacts[1].a_ends) EXPECT_NEAR(end.x(), 17.0, 1e-9);
  // The default is for real OSM, where touching neighbours share nodes: the 0.8 m overlap and
  // the 1.2 m gap are real there, and only the exact contact of the first two stays.
  const std::vector<Polygon2> mapped = {rectangle(0, 0, 10, 12), rectangle(10, 0.3, 17, 12.3),
                                        rectangle(18.2, -0.2, 26, 11.8)};
  const auto real = findBuildingContacts(mapped, BuildingContactParams{});
  ASSERT_EQ(real.size(), 1u);
  EXPECT_EQ(real[0].b, 1u);
  EXPECT_NEAR(real[0].distance, 0.0, 1e-9);
  EXPECT_EQ(findBuildingContacts(row, BuildingContactParams{}).size(), 0u);
}

TEST(BuildingContacts, DistantParallelAndPerpendicularWallsAreNotShared) {
  const BuildingContactParams p = simulatedPrior();
  // 3 m apart: a real gap, not the prior's misplacement.
  EXPECT_TRUE(findBuildingContacts({rectangle(0, 0, 10, 10), rectangle(13, 0, 20, 10)}, p).empty());
  // Close, but corner to corner: they face each other over 0.5 m only.
  EXPECT_TRUE(
      findBuildingContacts({rectangle(0, 0, 10, 10), rectangle(10.5, 9.5, 20, 20)}, p).empty());
  // Close, but turned by 15 degrees.
  const double c = std::cos(0.26), s = std::sin(0.26);
  Polygon2 turned;
  for (const auto& v : rectangle(0, 0, 8, 10))
    turned.push_back({10.3 + c * v.x() - s * v.y(), s * v.x() + c * v.y()});
  EXPECT_TRUE(findBuildingContacts({rectangle(0, 0, 10, 10), turned}, p).empty());
}

}  // namespace
}  // namespace osm_graph_slam
