#pragma once
// A tool's --config: the pipeline parameters as overrides over config/*.yaml (default
// config/kitti.yaml), loaded the same way by every offline tool.
#include <map>
#include <string>

#include "osm_graph_slam/slam/pipeline_params_io.h"

namespace osm_graph_slam::tools {

inline bool loadToolConfig(const std::map<std::string, std::string>& args,
                           SlamPipelineParams& params, std::string* error) {
  const std::string config_dir = std::string(OGS_SOURCE_DIR) + "/config";
  const auto config = args.find("config");
  return loadPipelineParams(config_dir,
                            config != args.end() ? config->second : config_dir + "/kitti.yaml",
                            params, error);
}

}  // namespace osm_graph_slam::tools
