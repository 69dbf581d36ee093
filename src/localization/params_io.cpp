#include "osm_graph_slam/localization/params_io.h"

#include "osm_graph_slam/landmarks/params_io.h"
#include "osm_graph_slam/registration/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, PoseUkfParams& p) {
  r.param("position_noise", p.position_noise);
  r.param("velocity_noise", p.velocity_noise);
  r.param("orientation_noise", p.orientation_noise);
  r.param("angular_rate_noise", p.angular_rate_noise);
  r.param("gyro_bias_noise", p.gyro_bias_noise);
  r.param("gyro_noise", p.gyro_noise);
  r.param("use_accelerometer", p.use_accelerometer);
  r.param("accel_noise", p.accel_noise);
  r.param("accel_velocity_noise", p.accel_velocity_noise);
  r.param("accel_bias_noise", p.accel_bias_noise);
  r.param("accel_bias_std", p.accel_bias_std);
  r.param("gravity", p.gravity);
  r.param("alpha", p.alpha);
  r.param("beta", p.beta);
  r.param("kappa", p.kappa);
}

void readParams(const ParamReader& r, LocalizationParams& p) {
  readParams(PrefixedParamReader(r, "registration"), p.registration);
  r.param("map_voxel_size", p.map_voxel_size);
  r.param("scan_voxel_size", p.scan_voxel_size);
  r.param("local_map_radius", p.local_map_radius);
  r.param("local_map_update_distance", p.local_map_update_distance);
  r.param("max_fitness", p.max_fitness);
  r.param("fitness_ratio", p.fitness_ratio);
  r.param("fitness_ratio_floor", p.fitness_ratio_floor);
  r.param("max_correction_trans", p.max_correction_trans);
  r.param("max_correction_angle", p.max_correction_angle);
  r.param("measurement_position_std", p.measurement_position_std);
  r.param("measurement_orientation_std", p.measurement_orientation_std);
  r.param("divergence_scans", p.divergence_scans);
  r.param("divergence_window", p.divergence_window);
  r.param("gnss_check_distance", p.gnss_check_distance);
  r.param("gnss_check_fixes", p.gnss_check_fixes);
  r.param("gnss_max_age", p.gnss_max_age);
  r.param("off_map_distance", p.off_map_distance);
  r.param("off_map_odometry", p.off_map_odometry);
  r.param("off_map_step_position_std", p.off_map_step_position_std);
  r.param("off_map_step_orientation_std", p.off_map_step_orientation_std);
  r.param("min_points", p.min_points);
  r.param("deskew", p.deskew);
  r.param("sweep_period", p.sweep.period);
  r.param("sweep_clockwise", p.sweep.clockwise);
  readParams(PrefixedParamReader(r, "ukf"), p.ukf);
  r.param("init_position_std", p.init_position_std);
  r.param("init_orientation_std", p.init_orientation_std);
  r.param("init_velocity_std", p.init_velocity_std);
  r.param("init_rate_std", p.init_rate_std);
  r.param("global_method", p.global_method);
  // Same layout as config/landmarks.yaml, under "landmarks/" (as loop_detection's).
  const PrefixedParamReader landmarks(r, "landmarks");
  readParams(PrefixedParamReader(landmarks, "extraction"), p.landmark_extraction);
  readParams(landmarks, p.landmarks);
  r.param("landmark_map", p.landmark_map);
  const PrefixedParamReader landmark_map(r, "landmark_map_params");
  landmark_map.param("association_distance", p.landmark_map_params.association_distance);
  landmark_map.param("min_observations", p.landmark_map_params.min_observations);
  landmark_map.param("tile_radius", p.landmark_map_params.tile_radius);
  landmark_map.param("tile_spacing", p.landmark_map_params.tile_spacing);
  r.param("global_ring_key_candidates", p.global_ring_key_candidates);
  r.param("global_candidates", p.global_candidates);
  r.param("global_max_descriptor_distance", p.global_max_descriptor_distance);
  r.param("global_false_match_rate", p.global_false_match_rate);
  r.param("global_impostor_distance", p.global_impostor_distance);
  r.param("global_impostor_pairs", p.global_impostor_pairs);
  r.param("global_max_fitness", p.global_max_fitness);
  r.param("global_min_overlap", p.global_min_overlap);
  r.param("global_overlap_distance", p.global_overlap_distance);
  r.param("global_overlap_samples", p.global_overlap_samples);
  r.param("global_overlap_impostor_places", p.global_overlap_impostor_places);
  r.param("global_structure_height", p.global_structure_height);
  r.param("global_coarse_max_correspondence", p.global_coarse_max_correspondence);
  r.param("global_voxel_size", p.global_voxel_size);
  r.param("global_ambiguity_ratio", p.global_ambiguity_ratio);
  r.param("global_side_view_offset", p.global_side_view_offset);
  r.param("global_osm_walls", p.global_osm_walls);
  r.param("global_osm_search_radius", p.global_osm_search_radius);
  r.param("global_osm_spacing", p.global_osm_spacing);
  r.param("global_osm_wall_radius", p.global_osm_wall_radius);
  r.param("global_osm_min_segments", p.global_osm_min_segments);
  r.param("global_osm_min_fitness", p.global_osm_min_fitness);
  r.param("global_osm_min_matched", p.global_osm_min_matched);
  r.param("global_osm_interval", p.global_osm_interval);
  r.param("global_osm_min_structure_overlap", p.global_osm_min_structure_overlap);
  r.param("global_confirm_after", p.global_confirm_after);
}

void readParams(const ParamReader& r, OsmLocalizerParams& p) {
  r.param("use_osm", p.use_osm);
  r.param("use_gnss", p.use_gnss);
  r.param("odometry_std_per_m", p.odometry_std_per_m);
  r.param("odometry_yaw_std_per_m", p.odometry_yaw_std_per_m);
  r.param("odometry_yaw_std_per_rad", p.odometry_yaw_std_per_rad);
  r.param("gnss_std", p.gnss_std);
  r.param("gnss_gate_chi2", p.gnss_gate_chi2);
  r.param("gnss_bias_std", p.gnss_bias_std);
  r.param("gnss_bias_tau", p.gnss_bias_tau);
  r.param("datum_std", p.datum_std);
  r.param("datum_walk_std_per_m", p.datum_walk_std_per_m);
  r.param("match_every_distance", p.match_every_distance);
  r.param("query_radius", p.query_radius);
  r.param("min_segments", p.min_segments);
  r.param("min_fitness", p.min_fitness);
  r.param("min_matched", p.min_matched);
  r.param("osm_std_xy", p.osm_std_xy);
  r.param("osm_std_yaw", p.osm_std_yaw);
  r.param("osm_gate_chi2", p.osm_gate_chi2);
  r.param("init_yaw_std", p.init_yaw_std);
}

}  // namespace osm_graph_slam
