#include "osm_graph_slam/io/yaml_param_reader.h"

#include <yaml-cpp/yaml.h>

#include <sstream>
#include <vector>

namespace osm_graph_slam {

struct YamlParamReader::Impl {
  YAML::Node root;

  /// The scalar at "a/b/c", or an undefined node.
  YAML::Node find(const std::string& key) const {
    YAML::Node node = YAML::Clone(root);
    std::stringstream ss(key);
    std::string part;
    while (std::getline(ss, part, '/')) {
      if (part.empty()) continue;
      if (!node.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
      node = node[part];
      if (!node) return YAML::Node(YAML::NodeType::Undefined);
    }
    return node.IsScalar() ? node : YAML::Node(YAML::NodeType::Undefined);
  }

  void collect(const YAML::Node& node, const std::string& prefix,
               std::vector<std::string>& out) const {
    if (!node.IsMap()) {
      out.push_back(prefix);
      return;
    }
    for (const auto& kv : node)
      collect(
          kv.second,
          prefix.empty() ? kv.first.as<std::string>() : prefix + "/" + kv.first.as<std::string>(),
          out);
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
  if (impl_->root.IsMap()) impl_->collect(impl_->root, "", out);
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
