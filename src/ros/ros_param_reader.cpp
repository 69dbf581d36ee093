#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {

bool RosParamReader::getDouble(const std::string& key, double* value) const {
  if (nh_.getParam(key, *value)) return true;
  int as_int = 0;  // "max_translation: 3" in YAML is an int on the parameter server
  if (!nh_.getParam(key, as_int)) return false;
  *value = as_int;
  return true;
}

bool RosParamReader::getInt(const std::string& key, int* value) const {
  return nh_.getParam(key, *value);
}

bool RosParamReader::getBool(const std::string& key, bool* value) const {
  return nh_.getParam(key, *value);
}

bool RosParamReader::getString(const std::string& key, std::string* value) const {
  return nh_.getParam(key, *value);
}

}  // namespace osm_graph_slam
