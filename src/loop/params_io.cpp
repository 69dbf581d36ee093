#include "osm_graph_slam/loop/params_io.h"

#include "osm_graph_slam/common/param_declaration.h"
#include "osm_graph_slam/landmarks/params_io.h"
#include "osm_graph_slam/registration/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, ScanContextParams& p) {
  r.param("num_rings", p.num_rings);
  r.param("num_sectors", p.num_sectors);
  r.param("max_radius", p.max_radius);
  r.param("min_radius", p.min_radius);
  r.param("sensor_height", p.sensor_height);
  r.param("max_height", p.max_height);
  r.param("min_height", p.min_height);
  r.param("sector_search_window", p.sector_search_window);
}

/// The correlative stage's own keys; its ground/height limits are the descriptor's.
static void readCorrelativeParams(const ParamReader& r, BevCorrelationParams& p) {
  r.param("cell_size", p.cell_size);
  r.param("sigma", p.sigma);
  r.param("max_range", p.max_range);
  r.param("query_point_spacing", p.query_point_spacing);
  r.param("yaw_step", p.yaw_step);
  r.param("peak_separation", p.peak_separation);
}

void readParams(const ParamReader& r, LoopDetectorParams& p) {
  r.param("method", p.method);
  readParams(PrefixedParamReader(r, "scan_context"), p.scan_context);
  // Same layout as config/landmarks.yaml, under "landmarks/".
  const PrefixedParamReader landmarks(r, "landmarks");
  readParams(PrefixedParamReader(landmarks, "extraction"), p.landmark_extraction);
  readParams(landmarks, p.landmarks);
  r.param("search_frame", p.search_frame);
  r.param("min_accum_distance_gap", p.min_accum_distance_gap);
  r.param("search_radius_base", p.search_radius_base);
  r.param("search_radius_per_meter", p.search_radius_per_meter);
  r.param("search_radius_max", p.search_radius_max);
  r.param("ring_key_candidates", p.ring_key_candidates);
  r.param("num_candidates", p.num_candidates);
  r.param("max_descriptor_distance", p.max_descriptor_distance);
  r.param("verify_odometry_nearest", p.verify_odometry_nearest);
  r.param("voxel_size", p.voxel_size);
  r.param("fine_query_voxel_size", p.fine_query_voxel_size);
  r.param("fine_max_source_points", p.fine_max_source_points);
  r.param("voxel_filter", p.voxel_filter);
  r.param("min_points", p.min_points);
  r.param("coarse_method", p.coarse_method);
  readCorrelativeParams(PrefixedParamReader(r, "correlative"), p.correlative);
  r.param("max_ambiguity", p.max_ambiguity);
  r.param("max_refinement_shift", p.max_refinement_shift);
  r.param("field_cache_size", p.field_cache_size);
  r.param("candidate_cache_size", p.candidate_cache_size);
  readDeclaredParams(r, p.cloud_store, nullptr);  // no choices among its keys: nothing to refuse
  r.param("coarse_voxel_size", p.coarse_voxel_size);
  r.param("coarse_max_correspondence_distance", p.coarse_max_correspondence_distance);
  r.param("coarse_max_fitness", p.coarse_max_fitness);
  readParams(PrefixedParamReader(r, "registration"), p.registration);
  r.param("max_fitness", p.max_fitness);
  r.param("overlap_distance", p.overlap_distance);
  r.param("min_overlap", p.min_overlap);
  r.param("seed_translation_from_odometry", p.seed_translation_from_odometry);
  r.param("retry_zero_translation_seed", p.retry_zero_translation_seed);
  r.param("stop_at_first_accepted", p.stop_at_first_accepted);
  r.param("check_odometry_consistency", p.check_odometry_consistency);
  r.param("odometry_translation_tolerance_base", p.odometry_translation_tolerance_base);
  r.param("odometry_translation_tolerance_per_meter", p.odometry_translation_tolerance_per_meter);
  r.param("odometry_yaw_tolerance_base", p.odometry_yaw_tolerance_base);
  r.param("odometry_yaw_tolerance_per_meter", p.odometry_yaw_tolerance_per_meter);
  r.param("translation_stddev_per_rms", p.translation_stddev_per_rms);
  r.param("rotation_stddev_per_rms", p.rotation_stddev_per_rms);
  r.param("min_translation_stddev", p.min_translation_stddev);
  r.param("max_translation_stddev", p.max_translation_stddev);
  r.param("min_rotation_stddev", p.min_rotation_stddev);
  r.param("max_rotation_stddev", p.max_rotation_stddev);
}

}  // namespace osm_graph_slam
