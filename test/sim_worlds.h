#pragma once
// Simulated worlds the gtests share, each built once per test binary (building one takes a
// second or two).
#include <gtest/gtest.h>

#include <string>

#include "osm_graph_slam/sim/simulator.h"

namespace osm_graph_slam::test {

/// The simulator with its default parameters (the 7 x 6 block city, a 1.5 km route).
inline const sim::UrbanSimulator& defaultSimulator() {
  static const sim::UrbanSimulator* sim = [] {
    auto* s = new sim::UrbanSimulator;
    std::string error;
    EXPECT_TRUE(s->build(sim::SimulationParams(), &error)) << error;
    return s;
  }();
  return *sim;
}

/// A small procedural city (seed 5, 4 x 3 blocks, a 600 m route).
inline const sim::UrbanSimulator& smallCity() {
  static const sim::UrbanSimulator* sim = [] {
    auto* s = new sim::UrbanSimulator;
    sim::SimulationParams p;
    p.seed = 5;
    p.city.blocks_x = 4;
    p.city.blocks_y = 3;
    p.route.length = 600.0;
    std::string error;
    EXPECT_TRUE(s->build(p, &error)) << error;
    return s;
  }();
  return *sim;
}

}  // namespace osm_graph_slam::test
