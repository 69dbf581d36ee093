#include "osm_graph_slam/registration/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, RegistrationParams& p) {
  r.param("method", p.method);
  r.param("num_threads", p.num_threads);
  r.param("max_iterations", p.max_iterations);
  r.param("max_correspondence_distance", p.max_correspondence_distance);
  r.param("transformation_epsilon", p.transformation_epsilon);
  r.param("k_correspondences", p.k_correspondences);
  r.param("ndt_resolution", p.ndt_resolution);
  r.param("ndt_step_size", p.ndt_step_size);
  r.param("gicp_covariance_epsilon", p.gicp_covariance_epsilon);
  r.param("vgicp_resolution", p.vgicp_resolution);
  r.param("min_correspondences", p.min_correspondences);
}

}  // namespace osm_graph_slam
