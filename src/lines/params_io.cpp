#include "osm_graph_slam/lines/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, LineSegmentExtractorParams& p) {
  r.param("merge_resolution", p.merge_resolution);
  r.param("distance_threshold", p.distance_threshold);
  r.param("max_iterations", p.max_iterations);
  r.param("sample_cell", p.sample_cell);
  r.param("cluster_tolerance", p.cluster_tolerance);
  r.param("min_cluster_size", p.min_cluster_size);
  r.param("min_segment_length", p.min_segment_length);
  r.param("max_segments", p.max_segments);
  r.param("max_consecutive_rejects", p.max_consecutive_rejects);
  r.param("refine", p.refine);
  r.param("seed", p.seed);  // unsigned: a negative value keeps the default
}

void readParams(const ParamReader& r, LineMatcherParams& p) {
  r.param("min_edge_angle_deg", p.min_edge_angle_deg);
  r.param("edge_endpoint_tolerance", p.edge_endpoint_tolerance);
  r.param("max_virtual_edge_distance", p.max_virtual_edge_distance);
  r.param("edge_angle_tolerance_deg", p.edge_angle_tolerance_deg);
  r.param("edge_length_slack", p.edge_length_slack);
  r.param("max_translation", p.max_translation);
  r.param("max_rotation_deg", p.max_rotation_deg);
  r.param("initial_max_translation", p.initial_max_translation);
  r.param("initial_ambiguity_margin", p.initial_ambiguity_margin);
  r.param("initial_distinct_heading_deg", p.initial_distinct_heading_deg);
  r.param("refine_k_nearest", p.refine_k_nearest);
  r.param("refine_rounds", p.refine_rounds);
  r.param("local_line_seed_distance", p.local_line_seed_distance);
  r.param("least_squares_polish", p.least_squares_polish);
  r.param("polish_iterations", p.polish_iterations);
  r.param("weight_distance", p.weight_distance);
  r.param("weight_coverage", p.weight_coverage);
  r.param("weight_translation", p.weight_translation);
  r.param("max_avg_distance", p.max_avg_distance);
  r.param("max_translation_fitness", p.max_translation_fitness);
  r.param("max_correspondence_distance", p.max_correspondence_distance);
  r.param("max_correspondence_angle_deg", p.max_correspondence_angle_deg);
  r.param("matched_distance", p.matched_distance);
  r.param("min_fitness", p.min_fitness);
  r.param("min_matched_segments", p.min_matched_segments);
  r.param("two_dof_max_angle_deg", p.two_dof_max_angle_deg);
  r.param("two_dof_along_scale", p.two_dof_along_scale);
  r.param("edge_information_xy", p.edge_information_xy);
  r.param("edge_information_theta", p.edge_information_theta);
  r.param("line_information_xy", p.line_information_xy);
  r.param("line_information_theta", p.line_information_theta);
  r.param("overlap_max_rotation_deg", p.overlap_max_rotation_deg);
  r.param("overlap_max_translation", p.overlap_max_translation);
  r.param("min_overlap_area", p.min_overlap_area);
  r.param("grid_cell", p.grid_cell);
  r.param("brute_force", p.brute_force);
}

}  // namespace osm_graph_slam
