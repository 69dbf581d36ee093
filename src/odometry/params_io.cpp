#include "osm_graph_slam/odometry/params_io.h"

#include "osm_graph_slam/registration/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, KeyframeTrackerParams& p) {
  // The registration's fields share the top level with the tracker's; only the method is renamed
  // ("registration_method" says more than "method" next to the keyframe thresholds).
  const std::string method = p.registration.method;
  readParams(r, p.registration);
  p.registration.method = method;
  r.param("registration_method", p.registration.method);
  r.param("keyframe_delta_trans", p.keyframe_delta_trans);
  r.param("keyframe_delta_angle", p.keyframe_delta_angle);
  r.param("keyframe_delta_time", p.keyframe_delta_time);
  r.param("constant_velocity_guess", p.constant_velocity_guess);
  r.param("max_fitness", p.max_fitness);
  r.param("max_correction_trans", p.max_correction_trans);
  r.param("max_correction_angle", p.max_correction_angle);
  r.param("min_points", p.min_points);
  r.param("lost_track_after", p.lost_track_after);
}

}  // namespace osm_graph_slam
