#include "osm_graph_slam/odometry/params_io.h"

#include "osm_graph_slam/registration/params_io.h"

namespace osm_graph_slam {
namespace {

/// The multi-cue tracker's keys, "multi_cue_" + the field's name.
void readMultiCueParams(const ParamReader& r, MultiCueTrackingParams& p) {
  r.param("multi_cue_sensor", p.sensor);
  r.param("multi_cue_keyframe_delta_trans", p.keyframe_delta_trans);
  r.param("multi_cue_keyframe_delta_angle", p.keyframe_delta_angle);
  r.param("multi_cue_max_fitness", p.max_fitness);
  r.param("multi_cue_fitness_ratio_floor", p.fitness_ratio_floor);
  r.param("multi_cue_max_range_jump_ratio", p.continuity.max_range_jump_ratio);
  MultiCueParams& g = p.registration;
  r.param("multi_cue_pyramid_levels", g.pyramid_levels);
  r.param("multi_cue_model_stride", g.model_stride);
  r.param("multi_cue_max_iterations_per_level", g.max_iterations_per_level);
  r.param("multi_cue_range_weight", g.range_weight);
  r.param("multi_cue_intensity_weight", g.intensity_weight);
  r.param("multi_cue_normal_weight", g.normal_weight);
  r.param("multi_cue_kernel", g.kernel);
  r.param("multi_cue_kernel_width", g.kernel_width);
  r.param("multi_cue_range_gate", g.range_gate);
  r.param("multi_cue_translation_epsilon", g.translation_epsilon);
  r.param("multi_cue_rotation_epsilon", g.rotation_epsilon);
  r.param("multi_cue_min_inliers", g.min_inliers);
}

}  // namespace

void readParams(const ParamReader& r, KeyframeTrackerParams& p) {
  // The registration's fields share the top level with the tracker's; only the method is renamed
  // ("registration_method" says more than "method" next to the keyframe thresholds).
  const std::string method = p.registration.method;
  readParams(r, p.registration);
  p.registration.method = method;
  r.param("registration_method", p.registration.method);
  r.param("tracker", p.tracker);
  readMultiCueParams(r, p.multi_cue);
  // One thread count for whichever registration tracks.
  p.multi_cue.registration.num_threads = p.registration.num_threads;
  r.param("keyframe_delta_trans", p.keyframe_delta_trans);
  r.param("keyframe_delta_angle", p.keyframe_delta_angle);
  r.param("keyframe_delta_time", p.keyframe_delta_time);
  r.param("constant_velocity_guess", p.constant_velocity_guess);
  r.param("max_fitness", p.max_fitness);
  r.param("fitness_ratio", p.fitness_ratio);
  r.param("fitness_ratio_floor", p.fitness_ratio_floor);
  r.param("max_correction_trans", p.max_correction_trans);
  r.param("max_correction_angle", p.max_correction_angle);
  r.param("min_points", p.min_points);
  r.param("lost_track_after", p.lost_track_after);
  r.param("max_prediction_gap", p.max_prediction_gap);
  r.param("restart_after_jump_back", p.restart_after_jump_back);
  r.param("guess", p.guess);
  r.param("pre_tracker_coarse_voxel", p.pre_tracker.coarse_voxel);
  r.param("pre_tracker_fine_voxel", p.pre_tracker.fine_voxel);
  r.param("pre_tracker_coarse_max_correspondence", p.pre_tracker.coarse_max_correspondence);
  r.param("pre_tracker_fine_max_correspondence", p.pre_tracker.fine_max_correspondence);
  r.param("pre_tracker_max_fitness", p.pre_tracker.max_fitness);
  r.param("pre_tracker_fitness_ratio", p.pre_tracker.fitness_ratio);
  r.param("pre_tracker_fitness_ratio_floor", p.pre_tracker.fitness_ratio_floor);
  r.param("pre_tracker_method", p.pre_tracker.method);
  r.param("pre_tracker_max_iterations", p.pre_tracker.max_iterations);
  r.param("recovery", p.recovery);
  r.param("recovery_yaw_step", p.recovery_yaw_step);
  r.param("recovery_yaw_steps", p.recovery_yaw_steps);
  r.param("reanchor_after_failures", p.reanchor_after_failures);
  r.param("deskew", p.deskew);
  r.param("deskew_max_interval", p.deskew_max_interval);
  r.param("sweep_period", p.sweep.period);
  r.param("sweep_clockwise", p.sweep.clockwise);
}

}  // namespace osm_graph_slam
