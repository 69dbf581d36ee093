#include "osm_graph_slam/landmarks/params_io.h"

namespace osm_graph_slam {

void readParams(const ParamReader& r, LandmarkExtractionParams& p) {
  r.param("min_range", p.min_range);
  r.param("max_range", p.max_range);
  r.param("sensor_height", p.sensor_height);
  r.param("ground_cell", p.ground_cell);
  r.param("band_min", p.band_min);
  r.param("band_max", p.band_max);
  r.param("cluster_cell", p.cluster_cell);
  r.param("min_points", p.min_points);
  r.param("max_radius", p.max_radius);
  r.param("min_radius", p.min_radius);
  r.param("min_vertical_coverage", p.min_vertical_coverage);
  r.param("slice_height", p.slice_height);
  r.param("max_elevation_deg", p.max_elevation_deg);
  r.param("sensor_above_origin", p.sensor_above_origin);
  r.param("min_confidence", p.min_confidence);
}

void readParams(const ParamReader& r, GeometricHierarchyParams& p) {
  r.param("descriptor_samples", p.descriptor_samples);
  r.param("descriptor_harmonics", p.descriptor_harmonics);
  r.param("max_edge_length", p.max_edge_length);
}

void readParams(const ParamReader& r, HierarchyMatchParams& p) {
  r.param("polygon_max_descriptor_distance", p.polygon_max_descriptor_distance);
  r.param("polygon_max_vertex_difference", p.polygon_max_vertex_difference);
  r.param("triangle_max_side_difference", p.triangle_max_side_difference);
  r.param("min_triangle_match_ratio", p.min_triangle_match_ratio);
  r.param("ransac_hypotheses", p.ransac_hypotheses);
  r.param("inlier_distance", p.inlier_distance);
  r.param("min_inliers", p.min_inliers);
  r.param("min_inlier_ratio", p.min_inlier_ratio);
  r.param("overlap_radius", p.overlap_radius);
  int seed = int(p.seed);
  r.param("seed", seed);
  p.seed = uint32_t(seed);
  r.param("triangle_tier_hypotheses", p.triangle_tier_hypotheses);
  r.param("triangle_tier_max_side_difference", p.triangle_tier_max_side_difference);
  r.param("hough_translation_bin", p.hough_translation_bin);
  r.param("hough_rotation_bin", p.hough_rotation_bin);
  r.param("hough_min_votes", p.hough_min_votes);
  r.param("probe_landmarks", p.probe_landmarks);
  r.param("early_exit_ratio", p.early_exit_ratio);
}

void readParams(const ParamReader& r, LandmarkPlaceRecognitionParams& p) {
  readParams(PrefixedParamReader(r, "hierarchy"), p.hierarchy);
  readParams(PrefixedParamReader(r, "matching"), p.match);
  r.param("polygon_neighbours", p.polygon_neighbours);
  r.param("max_candidates", p.max_candidates);
  r.param("min_votes", p.min_votes);
  r.param("min_landmarks", p.min_landmarks);
  r.param("min_indexed_vertices", p.min_indexed_vertices);
}

}  // namespace osm_graph_slam
