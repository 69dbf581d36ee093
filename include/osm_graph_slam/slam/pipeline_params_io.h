#pragma once
// Parameters of the whole pipeline from the same YAML files the launch files load: the
// defaults in config/<nodelet>.yaml, then an override file keyed by nodelet name.
#include <string>

#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/slam/slam_pipeline.h"

namespace osm_graph_slam {

/// Reads every stage from reader_for(nodelet name); used for the defaults and the overrides.
bool readPipelineParams(const ParamReader& reader, SlamPipelineParams& params, std::string* error);

/// config_dir/<nodelet>.yaml for each stage, then override_file (may be empty).
bool loadPipelineParams(const std::string& config_dir, const std::string& override_file,
                        SlamPipelineParams& params, std::string* error);

/// The localiser's: config_dir/localization.yaml and localization_advanced.yaml, then
/// override_file's "localization" block (may be empty), as the localization nodelet has them.
bool loadLocalizationParams(const std::string& config_dir, const std::string& override_file,
                            LocalizationParams& params, std::string* error);

}  // namespace osm_graph_slam
