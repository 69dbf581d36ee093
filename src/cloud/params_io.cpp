#include "osm_graph_slam/cloud/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, CloudPrefilterParams& p) {
  r.param("remove_invalid", p.remove_invalid);
  r.param("use_range_crop", p.use_range_crop);
  r.param("min_range", p.min_range);
  r.param("max_range", p.max_range);
  r.param("use_voxel_grid", p.use_voxel_grid);
  r.param("voxel_method", p.voxel_method);
  r.param("voxel_leaf_size", p.voxel_leaf_size);
  r.param("use_outlier_removal", p.use_outlier_removal);
  r.param("outlier_method", p.outlier_method);
  r.param("radius_search", p.radius_search);
  r.param("radius_min_neighbors", p.radius_min_neighbors);
  r.param("radius_backend", p.radius_backend);
  r.param("statistical_mean_k", p.statistical_mean_k);
  r.param("statistical_stddev", p.statistical_stddev);
  r.param("parallel_octants", p.parallel_octants);
  r.param("octant_margin", p.octant_margin);
  r.param("num_threads", p.num_threads);
}

void readParams(const ParamReader& r, WallPointExtractorParams& p) {
  r.param("horizon_height", p.horizon_height);
  r.param("min_range", p.min_range);
  r.param("max_range", p.max_range);
  r.param("voxel_size", p.voxel_size);
  r.param("k_neighbors", p.k_neighbors);
  r.param("max_normal_angle_deg", p.max_normal_angle_deg);
  r.param("max_neighbor_distance", p.max_neighbor_distance);
  r.param("normal_backend", p.normal_backend);
  r.param("num_threads", p.num_threads);
}

void readParams(const ParamReader& r, FloorDetectorParams& p) {
  r.param("enabled", p.enabled);
  r.param("floor_z", p.floor_z);
  r.param("floor_z_tolerance", p.floor_z_tolerance);
  r.param("min_range", p.min_range);
  r.param("max_range", p.max_range);
  r.param("normal_neighbours", p.normal_neighbours);
  r.param("max_normal_tilt_deg", p.max_normal_tilt_deg);
  r.param("ransac_distance", p.ransac_distance);
  r.param("ransac_iterations", p.ransac_iterations);
  r.param("min_inliers", p.min_inliers);
  r.param("max_floor_tilt_deg", p.max_floor_tilt_deg);
  r.param("rough_radius", p.rough_radius);
  r.param("rough_min_points", p.rough_min_points);
  r.param("rough_max_rms", p.rough_max_rms);
  r.param("warn_after_missing", p.warn_after_missing);
}

}  // namespace osm_graph_slam
