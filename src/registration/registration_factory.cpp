#include <stdexcept>

#include "registration_backends.h"

namespace osm_graph_slam {

std::unique_ptr<Registration> createRegistration(const RegistrationParams& params) {
  if (params.method == "fast_gicp") return detail::makeFastGicp(params);
  if (params.method == "fast_vgicp") return detail::makeFastVgicp(params);
  if (params.method == "pcl_gicp") return detail::makePclGicp(params);
  if (params.method == "pcl_ndt") return detail::makePclNdt(params);
  throw std::invalid_argument("unknown registration method '" + params.method +
                              "' (expected fast_gicp, fast_vgicp, pcl_gicp or pcl_ndt)");
}

}  // namespace osm_graph_slam
