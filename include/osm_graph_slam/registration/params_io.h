#pragma once
// Reading RegistrationParams from any ParamReader; keys are the field names ("method",
// "max_iterations", ...), as under "registration/" in config/loop_detection.yaml.
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam {

/// The method stays a string: createRegistration() rejects an unknown name.
void readParams(const ParamReader& reader, RegistrationParams& params);

}  // namespace osm_graph_slam
