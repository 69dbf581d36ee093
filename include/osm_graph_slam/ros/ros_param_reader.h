#pragma once
// ParamReader over a ros::NodeHandle (private namespace of a nodelet).
#include <ros/node_handle.h>

#include "osm_graph_slam/common/param_reader.h"

namespace osm_graph_slam {

class RosParamReader : public ParamReader {
 public:
  explicit RosParamReader(const ros::NodeHandle& nh) : nh_(nh) {}
  bool getDouble(const std::string& key, double* value) const override;
  bool getInt(const std::string& key, int* value) const override;
  bool getBool(const std::string& key, bool* value) const override;
  bool getString(const std::string& key, std::string* value) const override;

 private:
  ros::NodeHandle nh_;
};

}  // namespace osm_graph_slam
