#pragma once
// ParamReader over a YAML file (the same config/*.yaml the launch files load), for programs that
// run without a ROS master. Keys are paths through nested maps: "graph_backend/line_matcher/x".
#include <memory>
#include <string>
#include <vector>

#include "osm_graph_slam/common/param_reader.h"

namespace osm_graph_slam {

class YamlParamReader : public ParamReader {
 public:
  /// Loads path; ok() is false (and error() says why) for a missing or malformed file.
  static YamlParamReader fromFile(const std::string& path);
  static YamlParamReader fromString(const std::string& text);
  YamlParamReader(YamlParamReader&&) noexcept;
  ~YamlParamReader() override;

  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  /// Every leaf key ("a/b/c") in the document.
  std::vector<std::string> keys() const;

  bool getDouble(const std::string& key, double* value) const override;
  bool getInt(const std::string& key, int* value) const override;
  bool getBool(const std::string& key, bool* value) const override;
  bool getString(const std::string& key, std::string* value) const override;

 private:
  YamlParamReader();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string error_;
};

}  // namespace osm_graph_slam
