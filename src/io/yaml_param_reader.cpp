#include "osm_graph_slam/io/yaml_param_reader.h"

#include <yaml-cpp/yaml.h>

#include <sstream>
#include <vector>

namespace osm_graph_slam {

struct YamlParamReader::Impl {
  YAML::Node root;

  /// The scalar at "a/b/c", or an undefined node. Walks through const nodes (operator[] on a
  /// const node never inserts) and rebinds with reset(): `node = child` would assign through.
  YAML::Node find(const std::string& key) const {
    YAML::Node node;
    node.reset(root);
    std::stringstream ss(key);
    std::string part;
    while (std::getline(ss, part, '/')) {
      if (part.empty()) continue;
      if (!node.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
      const YAML::Node& parent = node;
      const YAML::Node child = parent[part];
      if (!child) return YAML::Node(YAML::NodeType::Undefined);
      node.reset(child);
    }
    return node.IsScalar() ? node : YAML::Node(YAML::NodeType::Undefined);
  }

  /// Leaf keys below node. Keys that are not scalars (a map or sequence used as a key, "? [a]")
  /// cannot be named by an "a/b/c" path and are skipped (keys() threw on them, fuzz_yaml_params);
  /// aliases can make the tree exponentially large, so at most kMaxKeys are listed.
  static constexpr size_t kMaxKeys = 100000;
  void collect(const YAML::Node& node, const std::string& prefix,
               std::vector<std::string>& out) const {
    if (out.size() >= kMaxKeys) return;
    if (!node.IsMap()) {
      out.push_back(prefix);
      return;
    }
    for (const auto& kv : node) {
      if (!kv.first.IsScalar()) continue;
      const std::string& name = kv.first.Scalar();
      collect(kv.second, prefix.empty() ? name : prefix + "/" + name, out);
    }
  }
};

YamlParamReader::YamlParamReader() : impl_(std::make_unique<Impl>()) {}
YamlParamReader::YamlParamReader(YamlParamReader&&) noexcept = default;
YamlParamReader::~YamlParamReader() = default;

YamlParamReader YamlParamReader::fromFile(const std::string& path) {
  YamlParamReader reader;
  try {
    reader.impl_->root = YAML::LoadFile(path);
  } catch (const std::exception& e) {
    reader.error_ = "cannot read parameters from '" + path + "': " + e.what();
  }
  return reader;
}

YamlParamReader YamlParamReader::fromString(const std::string& text) {
  YamlParamReader reader;
  try {
    reader.impl_->root = YAML::Load(text);
  } catch (const std::exception& e) {
    reader.error_ = std::string("malformed YAML: ") + e.what();
  }
  return reader;
}

std::vector<std::string> YamlParamReader::keys() const {
  std::vector<std::string> out;
  try {
    if (impl_->root.IsMap()) impl_->collect(impl_->root, "", out);
  } catch (const std::exception&) {
    // yaml-cpp throws on nodes it cannot convert; the keys listed so far stay.
  }
  return out;
}

template <typename T>
static bool convert(const YAML::Node& node, T* value) {
  if (!node.IsDefined()) return false;
  try {
    *value = node.as<T>();
    return true;
  } catch (const std::exception&) {
    return false;  // a wrong type leaves the default in place
  }
}

bool YamlParamReader::getDouble(const std::string& key, double* value) const {
  return convert(impl_->find(key), value);
}
bool YamlParamReader::getInt(const std::string& key, int* value) const {
  return convert(impl_->find(key), value);
}
bool YamlParamReader::getBool(const std::string& key, bool* value) const {
  return convert(impl_->find(key), value);
}
bool YamlParamReader::getString(const std::string& key, std::string* value) const {
  return convert(impl_->find(key), value);
}

}  // namespace osm_graph_slam
