// Keeps "one place of defaults" honest: every config/<nodelet>.yaml is read with the same
// readParams() functions the nodelets and the offline runner use, and
//  (a) every key in the file must be read by them or be a listed nodelet-only key,
//  (b) every value in the file must equal the code default of the field it sets,
//  (c) every key of an override file (config/kitti.yaml, ...) must be a key of that nodelet.
// The auditing reader sees the code default because readParams() hands each struct field (still
// holding its initialiser) to ParamReader::param().
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/cloud/params_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/lines/params_io.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/loop/params_io.h"
#include "osm_graph_slam/odometry/params_io.h"
#include "osm_graph_slam/osm/params_io.h"
#include "osm_graph_slam/radar/radar_slam.h"
#include "osm_graph_slam/radar/radar_stream.h"
#include "osm_graph_slam/registration/params_io.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/slam/params_io.h"
#include "test_data.h"

using namespace osm_graph_slam;

namespace {

/// Wraps a YAML reader; remembers every key read successfully with the value the field held
/// before (the code default when reading into a default-constructed struct) and the file's value.
class AuditingReader : public ParamReader {
 public:
  struct Read {
    std::string code_default;
    std::string file_value;
    bool equal = false;
  };

  explicit AuditingReader(const ParamReader& base) : base_(base) {}

  bool getDouble(const std::string& k, double* v) const override {
    const double before = *v;
    if (!base_.getDouble(k, v)) return false;
    const double tol = 1e-12 * std::max({1.0, std::abs(before), std::abs(*v)});
    note(k, text(before), text(*v), std::abs(before - *v) <= tol);
    return true;
  }
  bool getInt(const std::string& k, int* v) const override {
    const int before = *v;
    if (!base_.getInt(k, v)) return false;
    note(k, std::to_string(before), std::to_string(*v), before == *v);
    return true;
  }
  bool getBool(const std::string& k, bool* v) const override {
    const bool before = *v;
    if (!base_.getBool(k, v)) return false;
    note(k, before ? "true" : "false", *v ? "true" : "false", before == *v);
    return true;
  }
  bool getString(const std::string& k, std::string* v) const override {
    const std::string before = *v;
    if (!base_.getString(k, v)) return false;
    note(k, "'" + before + "'", "'" + *v + "'", before == *v);
    return true;
  }

  const std::map<std::string, Read>& reads() const { return reads_; }

 private:
  static std::string text(double v) {
    std::ostringstream ss;
    ss.precision(17);
    ss << v;
    return ss.str();
  }
  void note(const std::string& k, std::string code, std::string file, bool equal) const {
    reads_[k] = Read{std::move(code), std::move(file), equal};
  }

  const ParamReader& base_;
  mutable std::map<std::string, Read> reads_;
};

/// One nodelet's config files: how its stage reads them and which keys only the nodelet reads.
struct StageConfig {
  std::string nodelet;
  std::function<void(const ParamReader&)> read;  ///< into default-constructed structs
  std::set<std::string> nodelet_only;            ///< lists, which only the nodelet reads
  /// The files of its keys (disjoint); empty: config/<nodelet>.yaml.
  std::vector<std::string> files = {};
  std::vector<std::string> fileNames() const {
    return files.empty() ? std::vector<std::string>{nodelet} : files;
  }
};

std::vector<StageConfig> stages() {
  return {
      {"prefiltering",
       [](const ParamReader& r) {
         CloudPrefilterParams p;
         readParams(r, p);
         PrefilteringNodeletParams n;
         readParams(r, n);
       },
       {"sensor_to_base"}},
      {"scan_matching",
       [](const ParamReader& r) {
         KeyframeTrackerParams p;
         readParams(r, p);
         ScanMatchingNodeletParams n;
         readParams(r, n);
       },
       {}},
      {"floor_detection",
       [](const ParamReader& r) {
         FloorDetectorParams p;
         readParams(r, p);
       },
       {}},
      {"line_extraction",
       [](const ParamReader& r) {
         WallPointExtractorParams wall;
         readParams(PrefixedParamReader(r, "wall"), wall);
         LineSegmentExtractorParams segments;
         readParams(PrefixedParamReader(r, "segments"), segments);
         LineExtractionNodeletParams n;
         readParams(r, n);
       },
       {}},
      {"loop_detection",
       [](const ParamReader& r) {
         LoopDetectorParams p;
         readParams(r, p);
         LoopDetectionNodeletParams n;
         readParams(r, n);
       },
       {},
       {"loop_detection", "loop_detection_advanced"}},
      {"osm_buffer",
       [](const ParamReader& r) {
         OsmBufferParams buffer;
         readParams(r, buffer);
         OverpassParams overpass;
         readParams(r, overpass);
         OsmBufferNodeletParams n;
         readParams(r, n);
       },
       {"origin"}},
      {"graph_backend",
       [](const ParamReader& r) {
         GraphBackendParams p;
         std::string error;
         EXPECT_TRUE(readParams(r, p, &error)) << "graph_backend.yaml: " << error;
         GraphBackendNodeletParams n;
         readParams(r, n);
       },
       {},
       {"graph_backend", "graph_backend_advanced"}},
      {"localization",
       [](const ParamReader& r) {
         LocalizationParams p;
         readParams(r, p);
         LocalizationNodeletParams n;
         readParams(r, n);
       },
       {},
       {"localization", "localization_advanced"}},
      {"osm_localization",
       [](const ParamReader& r) {
         OsmLocalizerParams p;
         readParams(r, p);
         OsmLocalizationNodeletParams n;
         readParams(r, n);
       },
       {}},
      {"radar",
       [](const ParamReader& r) {
         std::string error;
         radar::RadarSlamParams p;  // the odometry's keys, graph/* and loop/*
         EXPECT_TRUE(radar::readSlamParams(r, p, &error)) << "radar.yaml: " << error;
         radar::RadarStreamParams stream;
         EXPECT_TRUE(radar::readParams(r, stream, &error)) << "radar.yaml: " << error;
         RadarOdometryNodeletParams n;
         EXPECT_TRUE(readParams(r, n, &error)) << "radar.yaml: " << error;
       },
       {}},
  };
}

/// File values that differ from the code default and cannot be fixed on this branch (the struct
/// is owned by another branch right now). KnownDisagreementsStillDisagree fails once one is
/// fixed, so this list cannot go stale.
const std::map<std::string, std::set<std::string>> kKnownDisagreements = {};

std::string configPath(const std::string& name) {
  return test::sourceDir() + "/config/" + name + ".yaml";
}

YamlParamReader loadConfig(const std::string& name) {
  YamlParamReader yaml = YamlParamReader::fromFile(configPath(name));
  EXPECT_TRUE(yaml.ok()) << yaml.error();
  return yaml;
}

/// Keys of the file that neither readParams nor the nodelet reads.
std::vector<std::string> unreadKeys(const YamlParamReader& yaml, const AuditingReader& audit,
                                    const std::set<std::string>& nodelet_only) {
  std::vector<std::string> out;
  for (const std::string& key : yaml.keys())
    if (!audit.reads().count(key) && !nodelet_only.count(key)) out.push_back(key);
  return out;
}

/// "key: file value vs code default" for every value that disagrees with the code.
std::map<std::string, std::string> disagreements(const AuditingReader& audit) {
  std::map<std::string, std::string> out;
  for (const auto& [key, read] : audit.reads())
    if (!read.equal)
      out[key] = "file says " + read.file_value + ", code default is " + read.code_default;
  return out;
}

}  // namespace

TEST(ConfigConsistency, EveryKeyOfEveryConfigFileIsRead) {
  for (const StageConfig& stage : stages()) {
    std::set<std::string> file_keys;
    for (const std::string& name : stage.fileNames()) {
      SCOPED_TRACE(configPath(name));
      const YamlParamReader yaml = loadConfig(name);
      ASSERT_TRUE(yaml.ok());
      const AuditingReader audit(yaml);
      stage.read(audit);
      EXPECT_GT(audit.reads().size(), 0u) << "nothing of " << name << ".yaml was read";
      for (const std::string& key : unreadKeys(yaml, audit, stage.nodelet_only))
        ADD_FAILURE() << "config/" << name << ".yaml: key '" << key
                      << "' is read by no readParams() and is not a listed nodelet-only key "
                         "(a typo, a removed parameter, or a wrong type in the file)";
      for (const std::string& key : yaml.keys()) {
        EXPECT_TRUE(file_keys.insert(key).second)
            << "config/" << name << ".yaml: '" << key << "' is in another file of " << stage.nodelet
            << " too (one place per key)";
      }
      for (const std::string& key : stage.nodelet_only)
        EXPECT_FALSE(audit.reads().count(key))
            << "'" << key << "' is read by readParams(): remove it from the nodelet-only list";
    }
    for (const std::string& key : stage.nodelet_only)
      EXPECT_TRUE(file_keys.count(key))
          << "config/" << stage.nodelet << ".yaml lacks the nodelet-only key '" << key << "'";
  }
}

TEST(ConfigConsistency, EveryFileValueEqualsTheCodeDefault) {
  for (const StageConfig& stage : stages()) {
    for (const std::string& name : stage.fileNames()) {
      const YamlParamReader yaml = loadConfig(name);
      ASSERT_TRUE(yaml.ok());
      const AuditingReader audit(yaml);
      stage.read(audit);
      const auto known =
          kKnownDisagreements.count(name) ? kKnownDisagreements.at(name) : std::set<std::string>{};
      for (const auto& [key, what] : disagreements(audit)) {
        if (known.count(key)) {
          std::cout << "[ KNOWN    ] config/" << name << ".yaml: '" << key << "': " << what << "\n";
          continue;
        }
        ADD_FAILURE() << "config/" << name << ".yaml: '" << key << "': " << what
                      << " (the file and the params struct must agree)";
      }
    }
  }
}

TEST(ConfigConsistency, KnownDisagreementsStillDisagree) {
  for (const auto& [name, keys] : kKnownDisagreements) {
    const YamlParamReader yaml = loadConfig(name);
    ASSERT_TRUE(yaml.ok());
    const AuditingReader audit(yaml);
    for (const StageConfig& stage : stages()) {
      const auto names = stage.fileNames();
      if (std::count(names.begin(), names.end(), name)) stage.read(audit);
    }
    const auto found = disagreements(audit);
    for (const std::string& key : keys)
      EXPECT_TRUE(found.count(key)) << "config/" << name << ".yaml: '" << key
                                    << "' now agrees with the code: drop it from "
                                       "kKnownDisagreements";
  }
}

// The audit itself must catch what it is for: a changed value and an unknown key.
TEST(ConfigConsistency, AuditCatchesAChangedValueAndAnUnknownKey) {
  const YamlParamReader yaml = YamlParamReader::fromString(R"(
min_range: 3.0
voxel_method: exact
min_rnage: 2.0
num_threads: "four"
base_link_frame: base_link
)");
  ASSERT_TRUE(yaml.ok()) << yaml.error();
  const AuditingReader audit(yaml);
  stages()[0].read(audit);  // prefiltering
  const auto found = disagreements(audit);
  EXPECT_EQ(found.size(), 2u);
  EXPECT_TRUE(found.count("min_range"));
  EXPECT_TRUE(found.count("voxel_method"));
  const auto unread = unreadKeys(yaml, audit, stages()[0].nodelet_only);
  // the typo, and a value of the wrong type (not read: the default stays)
  EXPECT_EQ(unread, (std::vector<std::string>{"min_rnage", "num_threads"}));
}

// The readers put each key into the right field (nested prefixes and renamed keys included).
TEST(ConfigConsistency, ReadersFillTheRightFields) {
  const YamlParamReader yaml = YamlParamReader::fromString(R"(
scan_matching:
  registration_method: pcl_ndt
  method: ignored_here
  ndt_resolution: 2.5
  keyframe_delta_trans: 4.0
line_extraction:
  wall: {horizon_height: 1.5, normal_backend: pcl}
  segments: {seed: 7, refine: false, min_range: 99.0}
loop_detection:
  scan_context: {num_sectors: 90}
  registration: {method: pcl_gicp, max_iterations: 12}
  max_iterations: 1000
osm_buffer:
  retry_max: 10.0
  overpass_url: http://localhost:1/api
  overpass_max_response_bytes: 1024
)");
  ASSERT_TRUE(yaml.ok()) << yaml.error();
  KeyframeTrackerParams tracker;
  readParams(PrefixedParamReader(yaml, "scan_matching"), tracker);
  EXPECT_EQ(tracker.registration.method, "pcl_ndt");
  EXPECT_DOUBLE_EQ(tracker.registration.ndt_resolution, 2.5);
  EXPECT_DOUBLE_EQ(tracker.keyframe_delta_trans, 4.0);
  EXPECT_DOUBLE_EQ(tracker.keyframe_delta_angle, KeyframeTrackerParams{}.keyframe_delta_angle);

  const PrefixedParamReader lines(yaml, "line_extraction");
  WallPointExtractorParams wall;
  readParams(PrefixedParamReader(lines, "wall"), wall);
  LineSegmentExtractorParams segments;
  readParams(PrefixedParamReader(lines, "segments"), segments);
  EXPECT_DOUBLE_EQ(wall.horizon_height, 1.5);
  EXPECT_EQ(wall.normal_backend, "pcl");
  EXPECT_DOUBLE_EQ(wall.min_range, WallPointExtractorParams{}.min_range);  // other block's key
  EXPECT_EQ(segments.seed, 7u);
  EXPECT_FALSE(segments.refine);

  LoopDetectorParams loop;
  readParams(PrefixedParamReader(yaml, "loop_detection"), loop);
  EXPECT_EQ(loop.scan_context.num_sectors, 90);
  EXPECT_EQ(loop.registration.method, "pcl_gicp");
  EXPECT_EQ(loop.registration.max_iterations, 12);

  OsmBufferParams buffer;
  OverpassParams overpass;
  readParams(PrefixedParamReader(yaml, "osm_buffer"), buffer);
  readParams(PrefixedParamReader(yaml, "osm_buffer"), overpass);
  EXPECT_DOUBLE_EQ(buffer.retry_max_s, 10.0);
  EXPECT_EQ(overpass.endpoint, "http://localhost:1/api");
  EXPECT_EQ(overpass.max_response_bytes, 1024u);
}

// Override files (config/kitti.yaml, ...) are keyed by nodelet name; every key must exist in that
// nodelet's defaults file, or the override silently does nothing.
TEST(ConfigConsistency, OverrideFilesOnlySetKnownKeys) {
  std::map<std::string, std::set<std::string>> known;
  for (const StageConfig& stage : stages()) {
    for (const std::string& name : stage.fileNames()) {
      const YamlParamReader yaml = loadConfig(name);
      for (const std::string& key : yaml.keys()) known[stage.nodelet].insert(key);
    }
  }
  int checked = 0;
  for (const std::string name : {"kitti", "mulran", "sim"}) {
    const YamlParamReader yaml = YamlParamReader::fromFile(configPath(name));
    ASSERT_TRUE(yaml.ok()) << yaml.error();
    for (const std::string& key : yaml.keys()) {
      const size_t slash = key.find('/');
      const std::string nodelet = key.substr(0, slash);
      ASSERT_TRUE(known.count(nodelet))
          << "config/" << name << ".yaml: '" << nodelet << "' is no nodelet of the launch file";
      EXPECT_TRUE(slash != std::string::npos && known[nodelet].count(key.substr(slash + 1)))
          << "config/" << name << ".yaml: '" << key << "' is not a parameter of " << nodelet
          << " (see config/" << nodelet << ".yaml)";
      ++checked;
    }
  }
  EXPECT_GT(checked, 0);
}

TEST(ConfigConsistency, MisspeltValuesAreErrorsNotSilentDefaults) {
  struct Case {
    const char* yaml;
    const char* expected;  ///< part of the error message
  };
  for (const Case& c : {Case{"loop_kernel: cauchi\n", "loop_kernel 'cauchi'"},
                        Case{"building_edge_kernel: Huber\n", "building_edge_kernel 'Huber'"},
                        Case{"mode: nonrigid\n", "mode 'nonrigid'"},
                        Case{"odometry_lateral_std_ratio: 0\n", "odometry_lateral_std_ratio"}}) {
    GraphBackendParams p;
    std::string error;
    EXPECT_FALSE(readParams(YamlParamReader::fromString(c.yaml), p, &error)) << c.yaml;
    EXPECT_NE(error.find(c.expected), std::string::npos) << error;
    const GraphBackendParams defaults;
    EXPECT_EQ(p.loops.loop_kernel, defaults.loops.loop_kernel) << "a bad value keeps the default";
    EXPECT_EQ(p.association.building_edge_kernel, defaults.association.building_edge_kernel);
    EXPECT_EQ(p.mode, defaults.mode);
    EXPECT_EQ(p.odometry.information.lateral_std_ratio,
              defaults.odometry.information.lateral_std_ratio);
  }
  GraphBackendParams p;
  std::string error;
  EXPECT_TRUE(readParams(YamlParamReader::fromString("loop_kernel: huber\n"), p, &error)) << error;
  EXPECT_EQ(p.loops.loop_kernel, "huber");
}

namespace {

/// Remembers every key a reader asks for (and finds none).
class RecordingReader : public ParamReader {
 public:
  bool getDouble(const std::string& k, double*) const override { return note(k); }
  bool getInt(const std::string& k, int*) const override { return note(k); }
  bool getBool(const std::string& k, bool*) const override { return note(k); }
  bool getString(const std::string& k, std::string*) const override { return note(k); }
  const std::set<std::string>& keys() const { return keys_; }

 private:
  bool note(const std::string& k) const {
    keys_.insert(k);
    return false;
  }
  mutable std::set<std::string> keys_;
};

/// A YAML value as the config files write it (a double always with a '.', which rosparam's YAML
/// 1.1 reader needs to read it as a float).
std::string yamlValue(double v) {
  std::ostringstream ss;
  ss.precision(15);
  ss << v;
  std::string s = ss.str();
  const size_t e = s.find('e');
  if (s.find('.') == std::string::npos) s.insert(e == std::string::npos ? s.size() : e, ".0");
  return s;
}
std::string yamlValue(int v) {
  return std::to_string(v);
}
std::string yamlValue(bool v) {
  return v ? "true" : "false";
}
std::string yamlValue(const std::string& v) {
  return v;
}

/// "key: default  # doc" of every key a params struct declares.
struct DeclaredLines {
  std::vector<std::string> keys;
  std::map<std::string, std::string> value, doc;
  template <class T>
  void operator()(const char* key, T& field, const char* text, const char* choices = nullptr) {
    keys.push_back(key);
    value[key] = yamlValue(field);
    doc[key] = choices ? std::string(choices) + ": " + text : std::string(text);
  }
  std::string line(const std::string& key) const {
    std::string head = key + ": " + value.at(key);
    head.resize(std::max<size_t>(head.size() + 1, 34), ' ');
    return head + "# " + doc.at(key);
  }
};

/// key -> comment of every top-level "key: value  # comment" line of a config file.
std::map<std::string, std::string> topLevelComments(const std::string& path) {
  std::map<std::string, std::string> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || !std::isalpha(static_cast<unsigned char>(line[0]))) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const size_t hash = line.find(" #", colon);
    std::string comment;
    if (hash != std::string::npos) {
      comment = line.substr(line.find_first_not_of(" #", hash));
      comment.erase(comment.find_last_not_of(' ') + 1);
    }
    out[line.substr(0, colon)] = comment;
  }
  return out;
}

}  // namespace

// graph_backend.yaml holds the keys a user tunes between vehicles and cities, with a comment
// each; graph_backend_advanced.yaml every other key. Together they list every key the back-end
// and its nodelet read.
TEST(ConfigConsistency, GraphBackendKeysAreSplitIntoBasicAndAdvanced) {
  const YamlParamReader basic = loadConfig("graph_backend");
  const YamlParamReader advanced = loadConfig("graph_backend_advanced");
  ASSERT_TRUE(basic.ok() && advanced.ok());
  const std::vector<std::string> basic_keys = basic.keys(), advanced_keys = advanced.keys();
  EXPECT_LE(basic_keys.size(), 25u) << "config/graph_backend.yaml is for the keys a user tunes";
  for (const auto& [key, comment] : topLevelComments(configPath("graph_backend")))
    EXPECT_FALSE(comment.empty()) << "config/graph_backend.yaml: '" << key << "' lacks a comment";
  const RecordingReader asked;
  for (const StageConfig& stage : stages())
    if (stage.nodelet == "graph_backend") stage.read(asked);
  EXPECT_GT(asked.keys().size(), 100u);
  for (const std::string& key : asked.keys())
    EXPECT_TRUE(std::count(basic_keys.begin(), basic_keys.end(), key) +
                    std::count(advanced_keys.begin(), advanced_keys.end(), key) ==
                1)
        << "'" << key << "' is read by the back-end but in neither config/graph_backend.yaml "
        << "nor config/graph_backend_advanced.yaml";
}

// The comment of a declared key in the config files is its declaration's one-line doc (the
// declaration is the one place of keys, defaults and docs; EveryFileValueEqualsTheCodeDefault
// checks the values). OGS_PRINT_DECLARED_YAML=1 prints every declared line to copy from.
TEST(ConfigConsistency, DeclaredBackendKeysCarryTheirDocInTheFiles) {
  DeclaredLines declared;
  GraphBackendParams params;
  params.visitAll(declared);
  if (std::getenv("OGS_PRINT_DECLARED_YAML"))
    for (const std::string& key : declared.keys) std::cout << declared.line(key) << "\n";
  std::map<std::string, std::string> comments = topLevelComments(configPath("graph_backend"));
  for (const auto& kv : topLevelComments(configPath("graph_backend_advanced"))) comments.insert(kv);
  for (const std::string& key : declared.keys) {
    ASSERT_TRUE(comments.count(key)) << "'" << key << "' is in neither graph_backend yaml file";
    EXPECT_EQ(comments[key], declared.doc.at(key))
        << "the comment of '" << key << "' differs from its declaration's doc; the line is\n"
        << declared.line(key);
  }
}
