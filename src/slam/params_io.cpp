#include "osm_graph_slam/slam/params_io.h"

namespace osm_graph_slam {
namespace {

/// Reads a robust-kernel name. A misspelt one is an error and keeps the default; kernelNamed()
/// would otherwise silently turn it into no kernel at all.
bool readKernelName(const ParamReader& r, const std::string& key, std::string& field,
                    std::string* error) {
  std::string name = field;
  r.param(key, name);
  if (name == "none" || name == "huber" || name == "cauchy") {
    field = name;
    return true;
  }
  if (error) *error = "unknown " + key + " '" + name + "' (none | huber | cauchy)";
  return false;
}

}  // namespace

bool readParams(const ParamReader& r, GraphBackendParams& p, std::string* error) {
  bool ok = true;
  r.param("use_osm", p.use_osm);
  std::string mode = toString(p.mode);
  r.param("mode", mode);
  if (!parseOsmMode(mode, &p.mode)) {
    ok = false;
    if (error) *error = "unknown mode '" + mode + "' (prior | rigid | non_rigid)";
  }
  r.param("use_imu", p.inputs.use_imu);
  r.param("imu_max_time_difference", p.inputs.imu_max_time_difference);
  r.param("initial_heading_max_age", p.inputs.initial_heading_max_age);
  r.param("gnss_max_gap", p.inputs.gnss_max_gap);
  r.param("gnss_max_time_difference", p.inputs.gnss_max_time_difference);
  r.param("odometry_min_std_xyz", p.odometry.min_std_xyz);
  r.param("odometry_max_std_xyz", p.odometry.max_std_xyz);
  r.param("odometry_min_std_rot", p.odometry.min_std_rot);
  r.param("odometry_max_std_rot", p.odometry.max_std_rot);
  r.param("odometry_min_std_yaw", p.odometry.min_std_yaw);
  r.param("odometry_max_std_yaw", p.odometry.max_std_yaw);
  r.param("odometry_max_fitness", p.odometry.max_fitness);
  r.param("odometry_lateral_std_ratio", p.odometry.lateral_std_ratio);
  r.param("odometry_hessian_weight", p.odometry.hessian_weight);
  r.param("odometry_prediction_error_scale", p.odometry.prediction_error_scale);
  r.param("reanchor_std_xyz", p.reanchor_std_xyz);
  r.param("reanchor_std_rot", p.reanchor_std_rot);
  r.param("gnss_prior_std", p.gnss_prior_std);
  r.param("gnss_prior_kernel_width", p.gnss_prior_kernel_width);
  r.param("gnss_reported_accuracy", p.gnss_reported_accuracy);
  r.param("gnss_min_reported_std", p.gnss_min_reported_std);
  r.param("gnss_first_yaw_std", p.gnss_first_yaw_std);
  r.param("gnss_bias_std", p.gnss_bias_std);
  r.param("gnss_bias_std_vertical", p.gnss_bias_std_vertical);
  r.param("gnss_altitude_std", p.gnss_altitude_std);
  r.param("gnss_bias_tau", p.gnss_bias_tau);
  r.param("gnss_bias_window", p.gnss_bias_window);
  r.param("ins_heading_std", p.ins_heading_std);
  r.param("ins_heading_span", p.ins_heading_span);
  r.param("ins_heading_kernel_width", p.ins_heading_kernel_width);
  r.param("anchor_std_xy", p.anchor_std_xy);
  r.param("anchor_std_yaw", p.anchor_std_yaw);
  if (!(p.odometry.prediction_error_scale >= 0.0)) {
    if (error) *error = "odometry_prediction_error_scale must be >= 0";
    p.odometry.prediction_error_scale = InformationParams{}.prediction_error_scale;
    ok = false;
  }
  if (!(p.odometry.hessian_weight >= 0.0)) {
    if (error) *error = "odometry_hessian_weight must be >= 0";
    p.odometry.hessian_weight = InformationParams{}.hessian_weight;
    ok = false;
  }
  if (!(p.odometry.lateral_std_ratio > 0.0)) {
    if (error) *error = "odometry_lateral_std_ratio must be > 0";
    p.odometry.lateral_std_ratio = InformationParams{}.lateral_std_ratio;
    ok = false;
  }
  r.param("imu_attitude_std", p.imu_attitude_std);
  r.param("floor_edges", p.floor_edges);
  r.param("floor_normal_std", p.floor_normal_std);
  r.param("floor_distance_std", p.floor_distance_std);
  r.param("floor_kernel_width", p.floor_kernel_width);
  r.param("floor_slope_change_deg", p.floor_slope_change_deg);
  r.param("floor_max_link_distance", p.floor_max_link_distance);
  r.param("floor_attitude_with_imu", p.floor_attitude_with_imu);
  r.param("odometry_attitude_std", p.odometry_attitude_std);
  if (!readKernelName(r, "loop_kernel", p.loop_kernel, error)) ok = false;
  r.param("loop_kernel_width", p.loop_kernel_width);
  r.param("initial_yaw_known", p.initial_yaw_known);
  r.param("initial_yaw", p.initial_yaw);
  r.param("osm_query_radius", p.osm_query_radius);
  r.param("osm_max_wait", p.osm_max_wait);
  r.param("min_keyframe_segments", p.min_keyframe_segments);
  r.param("use_global_priors", p.use_global_priors);
  r.param("global_min_fitness", p.global_min_fitness);
  r.param("global_min_matched", p.global_min_matched);
  r.param("global_prior_std_xy", p.global_prior_std_xy);
  r.param("global_prior_std_yaw", p.global_prior_std_yaw);
  r.param("local_min_fitness", p.local_min_fitness);
  r.param("local_min_matched", p.local_min_matched);
  r.param("local_visible_walls_only", p.local_visible_walls_only);
  r.param("local_min_visible_walls", p.local_min_visible_walls);
  if (!readKernelName(r, "building_edge_kernel", p.building_edge_kernel, error)) ok = false;
  r.param("building_edge_kernel_width", p.building_edge_kernel_width);
  r.param("building_edge_gate_chi2", p.building_edge_gate_chi2);
  r.param("local_edge_std_xy", p.local_edge_std_xy);
  r.param("local_edge_std_theta", p.local_edge_std_theta);
  r.param("building_edge_spacing", p.building_edge_spacing);
  r.param("local_edge_at_walls", p.local_edge_at_walls);
  r.param("building_prior_std_xy", p.building_prior_std_xy);
  r.param("building_prior_std_xy_without_gnss", p.building_prior_std_xy_without_gnss);
  r.param("building_prior_std_theta", p.building_prior_std_theta);
  r.param("osm_datum_std_xy", p.osm_datum_std_xy);
  r.param("osm_datum_std_theta", p.osm_datum_std_theta);
  if (!readKernelName(r, "osm_datum_kernel", p.osm_datum_kernel, error)) ok = false;
  r.param("osm_datum_kernel_width", p.osm_datum_kernel_width);
  r.param("osm_datum_std_xy_without_gnss", p.osm_datum_std_xy_without_gnss);
  if (!readKernelName(r, "osm_datum_kernel_without_gnss", p.osm_datum_kernel_without_gnss, error))
    ok = false;
  r.param("osm_datum_reassociate_distance", p.osm_datum_reassociate_distance);
  r.param("osm_datum_reassociate_distance_without_gnss",
          p.osm_datum_reassociate_distance_without_gnss);
  r.param("optimization_window", p.optimization_window);
  r.param("window_loop_chi2", p.window_loop_chi2);
  r.param("joint_optimization", p.joint_optimization);
  r.param("joint_odometry_weight", p.joint_odometry_weight);
  r.param("odometry_scale_window", p.odometry_scale_window);
  r.param("odometry_scale_std", p.odometry_scale_std);
  r.param("odometry_scale_walk_std", p.odometry_scale_walk_std);
  if (p.odometry_scale_window > 0.0 &&
      !(p.odometry_scale_std > 0.0 && p.odometry_scale_walk_std > 0.0)) {
    if (error) *error = "odometry_scale_std and odometry_scale_walk_std must be > 0";
    p.odometry_scale_window = 0.0;
    ok = false;
  }
  if (!(p.odometry_scale_window >= 0.0)) {
    if (error) *error = "odometry_scale_window must be >= 0";
    p.odometry_scale_window = 0.0;
    ok = false;
  }
  r.param("resolve_overlaps", p.resolve_overlaps);
  r.param("overlap_max_iterations", p.overlap_max_iterations);
  r.param("overlap_information", p.overlap_information);
  r.param("overlap_min_area", p.overlap_min_area);
  r.param("overlap_clearance", p.overlap_clearance);
  r.param("overlap_projection_max_translation", p.overlap_projection_max_translation);
  r.param("use_shared_walls", p.use_shared_walls);
  r.param("unobserved_buildings_fixed", p.unobserved_buildings_fixed);
  r.param("shared_wall_std", p.shared_wall_std);
  r.param("shared_wall_kernel_width", p.shared_wall_kernel_width);
  r.param("shared_wall_max_distance", p.shared_walls.max_distance);
  r.param("shared_wall_max_angle_deg", p.shared_walls.max_angle_deg);
  r.param("shared_wall_min_fraction", p.shared_walls.min_shared_fraction);
  r.param("shared_wall_min_length", p.shared_walls.min_shared_length);
  readParams(PrefixedParamReader(r, "line_matcher"), p.matcher);
  if (!readParams(PrefixedParamReader(r, "graph_optimizer"), p.optimizer, error)) ok = false;
  return ok;
}

bool readParams(const ParamReader& r, OptimizerOptions& p, std::string* error) {
  r.param("max_iterations", p.max_iterations);
  r.param("function_tolerance", p.function_tolerance);
  r.param("gradient_tolerance", p.gradient_tolerance);
  r.param("parameter_tolerance", p.parameter_tolerance);
  r.param("num_threads", p.num_threads);
  r.param("initial_trust_region_radius", p.initial_trust_region_radius);
  r.param("analytic_jacobians", p.analytic_jacobians);
  r.param("verbose", p.verbose);
  std::string library = p.sparse_library == SparseLibrary::kSuiteSparse   ? "suite_sparse"
                        : p.sparse_library == SparseLibrary::kEigenSparse ? "eigen_sparse"
                                                                          : "auto";
  r.param("sparse_library", library);
  r.param("auto_eigen_max_free_vertices", p.auto_eigen_max_free_vertices);
  if (library == "auto") {
    p.sparse_library = SparseLibrary::kAuto;
  } else if (library == "suite_sparse") {
    p.sparse_library = SparseLibrary::kSuiteSparse;
  } else if (library == "eigen_sparse") {
    p.sparse_library = SparseLibrary::kEigenSparse;
  } else {
    if (error)
      *error = "unknown sparse_library '" + library + "' (auto | suite_sparse | eigen_sparse)";
    return false;
  }
  return true;
}

}  // namespace osm_graph_slam
