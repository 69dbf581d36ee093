// OSM XML/PBF reading: real Karlsruhe extract (counts checked independently with a Python
// xml.etree scan of the same file), PBF written at run time, relations, clipped and broken input.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <osmium/io/any_input.hpp>
#include <osmium/io/any_output.hpp>
#include <sstream>

#include "osm_graph_slam/osm/osm_reader.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

const std::string kDrive5 = "osm/2011_09_26_drive_0005_sync.osm";
const std::string kDrive5Buildings = "osm/2011_09_26_drive_0005_sync_buildings.osm";

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

fs::path makeTempDir() {
  fs::path dir = fs::temp_directory_path() / ("ogs_osm_reader_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

const Building* findBuilding(const OsmData& data, int64_t id) {
  for (const Building& b : data.buildings) {
    if (b.id == id) return &b;
  }
  return nullptr;
}

size_t totalVertices(const OsmData& data) {
  size_t n = 0;
  for (const Building& b : data.buildings) n += b.outline_geo.size();
  return n;
}

/// The facts of drive 0005 established independently (Python xml.etree over the same file).
void expectDrive5Content(const OsmData& data) {
  ASSERT_TRUE(data.ok) << data.error;
  EXPECT_EQ(data.buildings.size(), 170u);
  EXPECT_EQ(data.stats.buildings, 170u);
  EXPECT_EQ(data.roads.size(), 91u);
  EXPECT_EQ(data.stats.skipped_missing_nodes, 0u);
  EXPECT_EQ(data.stats.skipped_open, 0u);
  EXPECT_EQ(data.stats.ways_seen, 341u);
  EXPECT_EQ(data.stats.relations_seen, 32u);  // route/restriction relations, none a building
  int64_t id_sum = 0;
  for (const Building& b : data.buildings) id_sum += b.id;
  EXPECT_EQ(id_sum, 26689654006LL);
  EXPECT_EQ(totalVertices(data), 1257u);

  const Building* kiosk = findBuilding(data, 90426027);
  ASSERT_NE(kiosk, nullptr);
  EXPECT_EQ(kiosk->tags.at("building"), "yes");
  EXPECT_EQ(kiosk->tags.at("shop"), "kiosk");
  EXPECT_EQ(kiosk->tags.size(), 4u);
  ASSERT_EQ(kiosk->outline_geo.size(), 4u);
  EXPECT_NEAR(kiosk->outline_geo[0].lat, 49.0109299, 1e-7);
  EXPECT_NEAR(kiosk->outline_geo[0].lon, 8.4233614, 1e-7);

  const Building* frisenhaus = findBuilding(data, 134631626);
  ASSERT_NE(frisenhaus, nullptr);
  EXPECT_EQ(frisenhaus->tags.size(), 16u);
  EXPECT_EQ(frisenhaus->tags.at("name"), "Frisenhaus");
  EXPECT_EQ(frisenhaus->tags.at("addr:street"), "Parkstraße");  // UTF-8 survives
  EXPECT_EQ(frisenhaus->outline_geo.size(), 11u);

  size_t tag_count = 0;
  for (const Building& b : data.buildings) tag_count += b.tags.size();
  EXPECT_EQ(tag_count, 886u);
  const size_t houses =
      std::count_if(data.buildings.begin(), data.buildings.end(),
                    [](const Building& b) { return b.tags.at("building") == "house"; });
  EXPECT_EQ(houses, 42u);
}

TEST(OsmReader, Drive5XmlBuildingsRoadsIdsAndTags) {
  const std::string path = test::sharedDataPath(kDrive5);
  OGS_REQUIRE_SHARED_FILE(path);
  expectDrive5Content(readOsmFile(path));
}

TEST(OsmReader, Drive5FromMemoryEqualsFromFile) {
  const std::string path = test::sharedDataPath(kDrive5);
  OGS_REQUIRE_SHARED_FILE(path);
  expectDrive5Content(parseOsmXml(readText(path)));
}

TEST(OsmReader, Drive5PbfWrittenByLibosmiumGivesTheSameResult) {
  const std::string path = test::sharedDataPath(kDrive5);
  OGS_REQUIRE_SHARED_FILE(path);
  const fs::path pbf = makeTempDir() / "drive5.osm.pbf";
  {
    osmium::io::Reader reader{path};
    osmium::io::Writer writer{pbf.string(), reader.header(), osmium::io::overwrite::allow};
    while (osmium::memory::Buffer buffer = reader.read()) writer(std::move(buffer));
    writer.close();
    reader.close();
  }
  ASSERT_GT(fs::file_size(pbf), 1000u);
  const OsmData from_pbf = readOsmFile(pbf.string());
  expectDrive5Content(from_pbf);
  const OsmData from_xml = readOsmFile(path);
  ASSERT_EQ(from_pbf.buildings.size(), from_xml.buildings.size());
  for (size_t i = 0; i < from_xml.buildings.size(); ++i) {
    const Building& a = from_xml.buildings[i];
    const Building* b = findBuilding(from_pbf, a.id);
    ASSERT_NE(b, nullptr) << a.id;
    EXPECT_EQ(a.tags, b->tags);
    ASSERT_EQ(a.outline_geo.size(), b->outline_geo.size());
    for (size_t k = 0; k < a.outline_geo.size(); ++k) {
      EXPECT_NEAR(a.outline_geo[k].lat, b->outline_geo[k].lat,
                  1e-7);  // PBF granularity 100 nano-deg
      EXPECT_NEAR(a.outline_geo[k].lon, b->outline_geo[k].lon, 1e-7);
    }
  }
  fs::remove_all(pbf.parent_path());
}

TEST(OsmReader, Drive5BuildingsOnlyFile) {
  const std::string path = test::sharedDataPath(kDrive5Buildings);
  OGS_REQUIRE_SHARED_FILE(path);
  const OsmData data = readOsmFile(path);
  ASSERT_TRUE(data.ok) << data.error;
  EXPECT_EQ(data.buildings.size(), 32u);
  EXPECT_TRUE(data.roads.empty());
  int64_t id_sum = 0;
  for (const Building& b : data.buildings) id_sum += b.id;
  EXPECT_EQ(id_sum, 3809302839LL);
  EXPECT_EQ(totalVertices(data), 249u);
}

// --- synthetic documents -------------------------------------------------------------------

std::string node(int64_t id, double lat, double lon) {
  std::ostringstream s;
  s.precision(10);
  s << "<node id=\"" << id << "\" lat=\"" << lat << "\" lon=\"" << lon << "\"/>\n";
  return s.str();
}

std::string way(int64_t id, const std::vector<int64_t>& refs, const std::string& tags) {
  std::ostringstream s;
  s << "<way id=\"" << id << "\">";
  for (int64_t r : refs) s << "<nd ref=\"" << r << "\"/>";
  s << tags << "</way>\n";
  return s.str();
}

std::string osmDoc(const std::string& body) {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osm version=\"0.6\" generator=\"test\">\n" +
         body + "</osm>\n";
}

/// A square building (way 10), a building whose corner node is missing (way 11, clipped), an open
/// building way (12), a road (20) and a multipolygon building relation (5) whose outer ring is
/// split over two ways (30, 31) with a courtyard (inner way 32) plus a second outer ring (33).
std::string syntheticDoc() {
  std::string body;
  // square 10: nodes 1..4
  body +=
      node(1, 49.0, 8.0) + node(2, 49.0, 8.0002) + node(3, 49.0002, 8.0002) + node(4, 49.0002, 8.0);
  // relation ring: nodes 101..104 (outer, two halves), 111..114 (inner), 121..123 (2nd outer)
  body += node(101, 49.01, 8.01) + node(102, 49.01, 8.012) + node(103, 49.012, 8.012) +
          node(104, 49.012, 8.01);
  body += node(111, 49.0105, 8.0105) + node(112, 49.0105, 8.0115) + node(113, 49.0115, 8.0115) +
          node(114, 49.0115, 8.0105);
  body += node(121, 49.02, 8.02) + node(122, 49.02, 8.021) + node(123, 49.021, 8.0205);
  const std::string b = "<tag k=\"building\" v=\"yes\"/>";
  body += way(10, {1, 2, 3, 4, 1}, b + "<tag k=\"name\" v=\"Square &amp; Co\"/>");
  body += way(11, {1, 2, 999, 1}, b);  // node 999 absent: clipped extract
  body += way(12, {1, 2, 3}, b);       // not closed
  body += way(20, {1, 3}, "<tag k=\"highway\" v=\"residential\"/>");
  body += way(30, {101, 102, 103}, "");
  body += way(31, {103, 104, 101}, "");
  body += way(32, {111, 112, 113, 114, 111}, "");
  body += way(33, {121, 122, 123, 121}, "");
  body +=
      "<relation id=\"5\"><member type=\"way\" ref=\"30\" role=\"outer\"/>"
      "<member type=\"way\" ref=\"31\" role=\"outer\"/><member type=\"way\" ref=\"32\" "
      "role=\"inner\"/><member type=\"way\" ref=\"33\" role=\"outer\"/>"
      "<tag k=\"type\" v=\"multipolygon\"/><tag k=\"building\" v=\"school\"/></relation>\n";
  // a relation whose member way is absent from the extract
  body +=
      "<relation id=\"6\"><member type=\"way\" ref=\"77\" role=\"outer\"/>"
      "<tag k=\"type\" v=\"multipolygon\"/><tag k=\"building\" v=\"yes\"/></relation>\n";
  return osmDoc(body);
}

TEST(OsmReader, SyntheticWaysRelationsAndSkips) {
  const OsmData data = parseOsmXml(syntheticDoc());
  ASSERT_TRUE(data.ok) << data.error;
  EXPECT_EQ(data.stats.skipped_missing_nodes, 1u);
  EXPECT_EQ(data.stats.skipped_open, 1u);
  EXPECT_EQ(data.stats.skipped_relations, 1u);
  ASSERT_EQ(data.roads.size(), 1u);
  EXPECT_EQ(data.roads[0].highway, "residential");
  EXPECT_EQ(data.roads[0].nodes_geo.size(), 2u);

  const Building* square = findBuilding(data, 10);
  ASSERT_NE(square, nullptr);
  EXPECT_EQ(square->outline_geo.size(), 4u);
  EXPECT_EQ(square->tags.at("name"), "Square & Co");

  // Relation 5: two outer rings; the split ring is joined into one 4-vertex outline.
  std::vector<const Building*> parts;
  for (const Building& b : data.buildings) {
    if (b.id == -5) parts.push_back(&b);
  }
  ASSERT_EQ(parts.size(), 2u);
  std::vector<size_t> sizes{parts[0]->outline_geo.size(), parts[1]->outline_geo.size()};
  std::sort(sizes.begin(), sizes.end());
  EXPECT_EQ(sizes, (std::vector<size_t>{3u, 4u}));
  EXPECT_NE(parts[0]->part, parts[1]->part);
  EXPECT_EQ(parts[0]->tags.at("building"), "school");
  for (const Building* p : parts) {
    for (const GeoPoint& g : p->outline_geo) {
      EXPECT_FALSE(g.lat > 49.0104 && g.lat < 49.0116 && g.lon > 8.0104 && g.lon < 8.0116)
          << "an inner (courtyard) vertex leaked into an outer ring";
    }
  }
  EXPECT_EQ(data.buildings.size(), 3u);
}

TEST(OsmReader, TruncatedXmlKeepsWhatWasReadAndSaysWhy) {
  const std::string doc = syntheticDoc();
  // Cut inside relation 5: the nodes and ways before it must survive.
  const std::string truncated = doc.substr(0, doc.find("<relation id=\"5\"") + 30);
  const OsmData data = parseOsmXml(truncated);
  EXPECT_FALSE(data.ok);
  EXPECT_NE(data.error.find("malformed OSM XML"), std::string::npos) << data.error;
  EXPECT_NE(data.error.find("line"), std::string::npos) << data.error;
  EXPECT_NE(data.error.find("kept the 1 buildings and 1 roads"), std::string::npos) << data.error;
  EXPECT_NE(findBuilding(data, 10), nullptr);
  EXPECT_EQ(data.roads.size(), 1u);

  // The same from a file, and from the real extract cut in the middle.
  const fs::path dir = makeTempDir();
  const fs::path file = dir / "truncated.osm";
  std::ofstream(file) << truncated;
  const OsmData from_file = readOsmFile(file.string());
  EXPECT_FALSE(from_file.ok);
  EXPECT_NE(findBuilding(from_file, 10), nullptr);
  const std::string real = test::sharedDataPath(kDrive5);
  if (fs::exists(real)) {
    const std::string text = readText(real);
    const OsmData half = parseOsmXml(text.substr(0, text.size() * 3 / 4));
    EXPECT_FALSE(half.ok);
    EXPECT_GT(half.buildings.size(), 0u);
    EXPECT_LT(half.buildings.size(), 170u);
    std::cout << "[OSM] 3/4 of drive 0005 XML: " << half.error << "\n";
  }
  fs::remove_all(dir);
}

TEST(OsmReader, MalformedInputsNeverCrash) {
  const std::string doc = syntheticDoc();
  const std::vector<std::string> inputs = {
      "",
      "not xml at all",
      "<html><body>504 Gateway Timeout</body></html>",
      "<?xml version=\"1.0\"?><osm version=\"0.6\"><node id=\"1\" lat=\"abc\" lon=\"8\"/></osm>",
      "<?xml version=\"1.0\"?><osm version=\"0.6\"><way id=\"1\"><nd ref=\"x\"/></way></osm>",
      std::string("<osm version=\"0.6\">\0\0\0", 22),
      doc.substr(0, doc.size() / 2),
      doc.substr(0, 57),
  };
  for (const std::string& input : inputs) {
    const OsmData data = parseOsmXml(input);
    EXPECT_FALSE(data.ok) << "accepted: " << input.substr(0, 60);
    EXPECT_FALSE(data.error.empty());
  }
  // Every prefix of a valid document: never crashes, never claims success unless complete.
  for (size_t cut = 0; cut < doc.size(); cut += 97) {
    const OsmData data = parseOsmXml(doc.substr(0, cut));
    EXPECT_FALSE(data.ok) << "prefix of " << cut << " bytes accepted";
  }
}

TEST(OsmReader, MissingOrUnsupportedFilesGiveErrors) {
  const OsmData missing = readOsmFile("/nonexistent/dir/map.osm");
  EXPECT_FALSE(missing.ok);
  EXPECT_NE(missing.error.find("cannot open"), std::string::npos) << missing.error;
  const OsmData wrong = readOsmFile("/tmp/map.txt");
  EXPECT_FALSE(wrong.ok);
  EXPECT_NE(wrong.error.find("suffix"), std::string::npos) << wrong.error;

  const fs::path dir = makeTempDir();
  const fs::path garbage = dir / "garbage.osm.pbf";
  std::ofstream(garbage) << "this is not a protobuf file at all, just text";
  const OsmData bad_pbf = readOsmFile(garbage.string());
  EXPECT_FALSE(bad_pbf.ok);
  EXPECT_FALSE(bad_pbf.error.empty());
  fs::remove_all(dir);
}

TEST(OsmReader, MemoryLimitsStopReadingWithAClearError) {
  OsmReadOptions options;
  options.max_objects = 2;
  const OsmData data = parseOsmXml(syntheticDoc(), options);
  EXPECT_FALSE(data.ok);
  EXPECT_NE(data.error.find("input too large"), std::string::npos) << data.error;
  options = OsmReadOptions();
  options.max_nodes = 5;
  const OsmData few_nodes = parseOsmXml(syntheticDoc(), options);
  EXPECT_FALSE(few_nodes.ok);
  EXPECT_NE(few_nodes.error.find("referenced nodes"), std::string::npos) << few_nodes.error;
}

}  // namespace
}  // namespace osm_graph_slam
