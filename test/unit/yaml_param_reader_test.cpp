#include <gtest/gtest.h>

#include <algorithm>

#include "osm_graph_slam/io/yaml_param_reader.h"

using namespace osm_graph_slam;

TEST(YamlParamReader, NestedKeysTypesAndDefaults) {
  const YamlParamReader r = YamlParamReader::fromString(R"(
graph_backend:
  mode: rigid
  osm_query_radius: 40
  use_osm: false
  line_matcher:
    max_translation: 2.5
    refine_rounds: 3
)");
  ASSERT_TRUE(r.ok()) << r.error();
  std::string mode = "non_rigid";
  double radius = 35.0, translation = 3.0, missing = 7.0;
  int rounds = 2;
  bool use_osm = true;
  r.param("graph_backend/mode", mode);
  r.param("graph_backend/osm_query_radius", radius);  // an int in YAML, read as double
  r.param("graph_backend/use_osm", use_osm);
  const PrefixedParamReader matcher(r, "graph_backend/line_matcher");
  matcher.param("max_translation", translation);
  matcher.param("refine_rounds", rounds);
  matcher.param("not_there", missing);
  EXPECT_EQ(mode, "rigid");
  EXPECT_DOUBLE_EQ(radius, 40.0);
  EXPECT_FALSE(use_osm);
  EXPECT_DOUBLE_EQ(translation, 2.5);
  EXPECT_EQ(rounds, 3);
  EXPECT_DOUBLE_EQ(missing, 7.0);  // missing keys keep the default
  int wrong_type = 5;
  r.param("graph_backend/mode", wrong_type);  // "rigid" is no int: default kept
  EXPECT_EQ(wrong_type, 5);
  auto keys = r.keys();
  std::sort(keys.begin(), keys.end());
  ASSERT_EQ(keys.size(), 5u);
  EXPECT_EQ(keys[0], "graph_backend/line_matcher/max_translation");
}

TEST(YamlParamReader, MalformedAndMissingFilesSayWhy) {
  EXPECT_FALSE(YamlParamReader::fromString("a: [1, 2").ok());
  const YamlParamReader missing = YamlParamReader::fromFile("/nonexistent/config.yaml");
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.error().find("/nonexistent/config.yaml"), std::string::npos);
  double v = 1.0;
  missing.param("x", v);
  EXPECT_DOUBLE_EQ(v, 1.0);
}
