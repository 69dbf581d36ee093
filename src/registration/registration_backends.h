#pragma once
// Private factory functions of the registration back-ends (one .cpp each, templates stay there).
#include <memory>

#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam::detail {

std::unique_ptr<Registration> makeFastGicp(const RegistrationParams& params);
std::unique_ptr<Registration> makeFastVgicp(const RegistrationParams& params);
std::unique_ptr<Registration> makePclGicp(const RegistrationParams& params);
std::unique_ptr<Registration> makePclNdt(const RegistrationParams& params);

}  // namespace osm_graph_slam::detail
