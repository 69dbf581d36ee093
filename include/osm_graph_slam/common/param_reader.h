#pragma once
// A source of named parameters ("line_matcher/max_translation"), so that every stage's
// parameters are read by one function whether they come from the ROS parameter server (nodelets)
// or a YAML file (offline runner). The params structs' initialisers stay the only defaults: a
// missing key leaves the field as it is.
#include <string>

namespace osm_graph_slam {

class ParamReader {
 public:
  virtual ~ParamReader() = default;
  virtual bool getDouble(const std::string& key, double* value) const = 0;
  virtual bool getInt(const std::string& key, int* value) const = 0;
  virtual bool getBool(const std::string& key, bool* value) const = 0;
  virtual bool getString(const std::string& key, std::string* value) const = 0;

  void param(const std::string& key, double& value) const { getDouble(key, &value); }
  void param(const std::string& key, int& value) const { getInt(key, &value); }
  void param(const std::string& key, bool& value) const { getBool(key, &value); }
  void param(const std::string& key, std::string& value) const { getString(key, &value); }
  void param(const std::string& key, unsigned& value) const {
    int v = static_cast<int>(value);
    if (getInt(key, &v) && v >= 0) value = static_cast<unsigned>(v);
  }
};

/// Reads keys below a namespace of another reader ("ns/key").
class PrefixedParamReader : public ParamReader {
 public:
  PrefixedParamReader(const ParamReader& base, std::string prefix)
      : base_(base), prefix_(std::move(prefix)) {}
  bool getDouble(const std::string& k, double* v) const override {
    return base_.getDouble(prefix_ + "/" + k, v);
  }
  bool getInt(const std::string& k, int* v) const override {
    return base_.getInt(prefix_ + "/" + k, v);
  }
  bool getBool(const std::string& k, bool* v) const override {
    return base_.getBool(prefix_ + "/" + k, v);
  }
  bool getString(const std::string& k, std::string* v) const override {
    return base_.getString(prefix_ + "/" + k, v);
  }

 private:
  const ParamReader& base_;
  std::string prefix_;
};

}  // namespace osm_graph_slam
