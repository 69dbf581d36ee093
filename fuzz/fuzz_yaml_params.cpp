// YamlParamReader: parse, list every key, read every key as each type.
#include <cstdint>
#include <string>

#include "osm_graph_slam/io/yaml_param_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto reader = osm_graph_slam::YamlParamReader::fromString(
      std::string(reinterpret_cast<const char*>(data), size));
  if (!reader.ok()) return 0;
  size_t n = 0;
  for (const std::string& key : reader.keys()) {
    if (++n > 200) break;  // lookups are linear; a bounded number keeps executions short
    double d;
    int i;
    bool b;
    std::string s;
    reader.getDouble(key, &d);
    reader.getInt(key, &i);
    reader.getBool(key, &b);
    reader.getString(key, &s);
  }
  return 0;
}
