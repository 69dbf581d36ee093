#include "osm_graph_slam/slam/pipeline_params_io.h"

#include <utility>

#include "osm_graph_slam/cloud/params_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/lines/params_io.h"
#include "osm_graph_slam/localization/params_io.h"
#include "osm_graph_slam/loop/params_io.h"
#include "osm_graph_slam/odometry/params_io.h"
#include "osm_graph_slam/osm/params_io.h"
#include "osm_graph_slam/slam/params_io.h"

namespace osm_graph_slam {

bool readPipelineParams(const ParamReader& r, SlamPipelineParams& p, std::string* error) {
  readParams(PrefixedParamReader(r, "prefiltering"), p.prefilter);
  readParams(PrefixedParamReader(r, "scan_matching"), p.tracker);
  if (const std::string why = p.tracker.validate(); !why.empty()) {
    if (error) *error = "scan_matching: " + why;  // at start, not at the first scan
    return false;
  }
  readParams(PrefixedParamReader(r, "floor_detection"), p.floor);
  readParams(PrefixedParamReader(r, "line_extraction/wall"), p.wall);
  readParams(PrefixedParamReader(r, "line_extraction/segments"), p.segments);
  readParams(PrefixedParamReader(r, "loop_detection"), p.loop);
  readParams(PrefixedParamReader(r, "osm_buffer"), p.osm);
  return readParams(PrefixedParamReader(r, "graph_backend"), p.backend, error);
}

bool loadPipelineParams(const std::string& config_dir, const std::string& override_file,
                        SlamPipelineParams& params, std::string* error) {
  // Each config/<file>.yaml holds its nodelet's keys at its top level; graph_backend's and
  // loop_detection's are split into the keys a user tunes and the advanced ones (disjoint).
  const std::pair<const char*, const char*> files[] = {
      {"prefiltering", "prefiltering"},
      {"scan_matching", "scan_matching"},
      {"floor_detection", "floor_detection"},
      {"line_extraction", "line_extraction"},
      {"loop_detection", "loop_detection"},
      {"loop_detection_advanced", "loop_detection"},
      {"osm_buffer", "osm_buffer"},
      {"graph_backend", "graph_backend"},
      {"graph_backend_advanced", "graph_backend"}};
  for (const auto& [name, nodelet] : files) {
    const std::string path = config_dir + "/" + name + ".yaml";
    const YamlParamReader file = YamlParamReader::fromFile(path);
    if (!file.ok()) {
      if (error) *error = file.error();
      return false;
    }
    // Present the file as if it were keyed by nodelet name, like an override file.
    struct Nested : ParamReader {
      const YamlParamReader& file;
      std::string prefix;
      Nested(const YamlParamReader& f, std::string p) : file(f), prefix(std::move(p) + "/") {}
      std::string strip(const std::string& key) const {
        return key.rfind(prefix, 0) == 0 ? key.substr(prefix.size()) : std::string("\x01");
      }
      bool getDouble(const std::string& k, double* v) const override {
        return file.getDouble(strip(k), v);
      }
      bool getInt(const std::string& k, int* v) const override { return file.getInt(strip(k), v); }
      bool getBool(const std::string& k, bool* v) const override {
        return file.getBool(strip(k), v);
      }
      bool getString(const std::string& k, std::string* v) const override {
        return file.getString(strip(k), v);
      }
    } nested(file, nodelet);
    if (!readPipelineParams(nested, params, error)) {
      if (error) *error = path + ": " + *error;
      return false;
    }
  }
  if (override_file.empty()) return true;
  const YamlParamReader overrides = YamlParamReader::fromFile(override_file);
  if (!overrides.ok()) {
    if (error) *error = overrides.error();
    return false;
  }
  if (!readPipelineParams(overrides, params, error)) {
    if (error) *error = override_file + ": " + *error;
    return false;
  }
  return true;
}

bool loadLocalizationParams(const std::string& config_dir, const std::string& override_file,
                            LocalizationParams& params, std::string* error) {
  for (const char* name : {"/localization.yaml", "/localization_advanced.yaml"}) {
    const YamlParamReader file = YamlParamReader::fromFile(config_dir + name);
    if (!file.ok()) {
      if (error) *error = file.error();
      return false;
    }
    readParams(file, params);
  }
  if (!override_file.empty()) {
    const YamlParamReader overrides = YamlParamReader::fromFile(override_file);
    if (!overrides.ok()) {
      if (error) *error = overrides.error();
      return false;
    }
    readParams(PrefixedParamReader(overrides, "localization"), params);
  }
  return true;
}

}  // namespace osm_graph_slam
