#pragma once
// Line-segment scan matching (OSM thesis §3.3, §3.5): edge-pair search within translation and
// rotation bounds, line-pair refinement from the best edge transform, the specialised fitness
// (eq. 3.1-3.4), an information matrix by feature type (§3.3.5), and the overlap-removal search.
#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"
#include "osm_graph_slam/lines/line_geometry.h"

namespace osm_graph_slam {

struct LineMatcherParams {
  // --- edges (§3.3.1) ---
  double min_edge_angle_deg = 30.0;        ///< lines closer to parallel form no edge
  double edge_endpoint_tolerance = 1.0;    ///< corner within this of both segments: angular edge
  double max_virtual_edge_distance = 6.0;  ///< virtual corner at most this beyond each segment
  double edge_angle_tolerance_deg = 6.0;   ///< opening angles of a matched edge pair agree within
  double edge_length_slack = 2.0;  ///< arm-length signature: shorter side's arm <= other + slack
  // --- search bounds (§3.3.2), deviation from the initial guess ---
  double max_translation = 3.0;    ///< [m]
  double max_rotation_deg = 15.0;  ///< ignored when the rotation is unbounded (first keyframe)
  /// Translation bound of the first pose (global matching with unbounded rotation): the GNSS
  /// error plus the OSM map's own offset, which is not the 3 m of a tracked keyframe: on the real
  /// drive kitti_raw_0005 the outlines sit 4.6 m from the RTK fix (doc/real_data.md).
  double initial_max_translation = 8.0;  ///< [m]
  /// First pose: refuse a match when a hypothesis whose heading differs by more than
  /// initial_distinct_heading_deg scores within this of the best (a wider window finds more
  /// look-alike corners; 0: no test).
  double initial_ambiguity_margin = 10.0;
  double initial_distinct_heading_deg = 10.0;
  // --- line-pair refinement (§3.3.3) ---
  int refine_k_nearest = 3;  ///< target segments tried per source segment
  int refine_rounds = 2;     ///< rounds while the best transform keeps improving
  /// Local matching also starts from every wall/segment line pair whose segments lie within this
  /// of each other at the guess (0: off, only the k nearest within max_correspondence_distance).
  /// A building seen through one facade has no corner to match, and a prior more than
  /// max_correspondence_distance off across that facade is otherwise never matched.
  double local_line_seed_distance = 3.0;  ///< [m]
  bool least_squares_polish = true;       ///< final Gauss-Newton on endpoint-to-line distances
  int polish_iterations = 6;
  // --- fitness (§3.3.4, eq. 3.1-3.4) ---
  double weight_distance = 1.0;          ///< A
  double weight_coverage = 1.0;          ///< B
  double weight_translation = 0.1;       ///< C
  double max_avg_distance = 1.0;         ///< MaxAvgDistance [m]
  double max_translation_fitness = 3.0;  ///< MaxTranslation [m]
  /// Per-segment distance truncation and nearest-neighbour search radius: a clutter segment with
  /// no counterpart costs this much instead of its distance to an arbitrary far wall [m].
  double max_correspondence_distance = 1.0;
  double max_correspondence_angle_deg = 20.0;  ///< nearest neighbours must be this parallel
  double matched_distance = 0.3;  ///< a source segment this close to its neighbour is matched [m]
  // --- result ---
  /// Below: success = false. Local matching sees a building partly (unseen walls cost the full
  /// correspondence distance), so good local matches score around -40..+40, global ones 50..100.
  double min_fitness = -50.0;
  int min_matched_segments = 1;
  double two_dof_max_angle_deg = 15.0;  ///< matched walls all within this: only 2 DOF
  /// Information kept along the unconstrained direction. Tiny on purpose: a building seen only
  /// through one facade gets hundreds of such edges, and 1e-3 of each slid it along the street by
  /// up to 2.6 m (measured: observed buildings 0.52 -> 0.26 m mean error with 1e-6).
  double two_dof_along_scale = 1e-6;
  double edge_information_xy = 100.0;  ///< §3.3.5: edge-based constraints weigh more
  double edge_information_theta = 1000.0;
  double line_information_xy = 25.0;
  double line_information_theta = 250.0;
  // --- overlap removal (§3.5) ---
  /// Overlap removal bounds. The thesis allows 60 deg; on the simulated Karlsruhe drive 60 deg /
  /// 20 m turned unobserved buildings by up to 15 deg and moved them up to 15 m to clear a
  /// neighbour, while 10 deg / 5 m halved the error of all buildings (1.35 -> 0.62 m).
  double overlap_max_rotation_deg = 10.0;
  double overlap_max_translation = 5.0;
  double min_overlap_area = 0.05;  ///< [m^2] less counts as separated (shared walls touch)
  // --- implementation ---
  double grid_cell = 1.5;    ///< target spatial index cell [m]
  bool brute_force = false;  ///< reference: every edge pair, no index, no pruning, no early stop
};

enum class MatchMode { kGlobal, kLocal, kOverlap };
enum class MatchFeature { kNone, kEdge, kLine };
const char* toString(MatchFeature f);

struct LineMatchStats {
  size_t source_segments = 0, target_segments = 0;
  size_t source_edges = 0, target_edges = 0;
  size_t edge_pairs_total = 0;      ///< brute-force search space |E_s| * |E_t|
  size_t edge_pairs_in_bounds = 0;  ///< pairs surviving the signature and bound pruning
  size_t hypotheses_evaluated = 0;  ///< fitness evaluations of edge hypotheses
  size_t line_pairs_evaluated = 0;  ///< fitness evaluations of line-pair refinements
  double ms = 0.0;
};

struct LineMatchResult {
  bool success = false;
  /// Maps the source frame into the target frame (like the initial guess it refines).
  Pose2 transform;
  double fitness = -1e300;
  MatchFeature feature = MatchFeature::kNone;
  int matched_segments = 0;
  /// Only two DOF are constrained (all matched walls parallel): translation along the wall is
  /// the guess's. constrained_normal is the constrained direction (target frame).
  bool two_dof = false;
  Eigen::Vector2d constrained_normal = Eigen::Vector2d::Zero();
  /// Information of (x, y, theta) of `transform`, translation in the target frame: by feature
  /// type, scaled by (fitness - min_fitness) / (100 B - min_fitness) in [0, 1]; nearly zero
  /// along the wall when two_dof.
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  /// Length-weighted centre of the matched source walls (target frame): where the walls pin the
  /// transform. `information` is taken there, not at the transform's origin (see leverInformation).
  Eigen::Vector2d matched_centre = Eigen::Vector2d::Zero();
  double avg_distance = 0.0, coverage = 0.0, translation = 0.0;  ///< terms of the fitness
  /// First pose (unbounded rotation) only: the best fitness of a hypothesis with a heading more
  /// than initial_distinct_heading_deg away from the result (-inf: none).
  double runner_up_fitness = -std::numeric_limits<double>::infinity();
  LineMatchStats stats;
  std::string message;  ///< why it failed, when it did
};

class LineMatcher {
 public:
  explicit LineMatcher(const LineMatcherParams& params = {}) : params_(params) {}

  /// Global matching: keyframe segments (base_link) -> segments of all nearby buildings (map).
  /// guess = keyframe pose in the map; rotation_unbounded for the first keyframe.
  LineMatchResult matchGlobal(const std::vector<LineSegment2>& keyframe_segments,
                              const std::vector<LineSegment2>& building_segments,
                              const Pose2& guess, bool rotation_unbounded = false) const;

  /// Local matching: one building's segments (building frame) -> keyframe segments (map).
  /// guess = the building's pose in the map; the result is the corrected building pose.
  LineMatchResult matchLocal(const std::vector<LineSegment2>& building_segments,
                             const std::vector<LineSegment2>& keyframe_segments,
                             const Pose2& guess) const;

  /// Overlap removal (§3.5): among the edge and line transforms of building A (outline in its
  /// frame, pose guess) onto building B (outline in the map) with rotation <= 60 deg that leave
  /// no overlap, the one of minimal translation. success = false if none does.
  LineMatchResult removeOverlap(const Polygon2& building_a, const Pose2& guess,
                                const Polygon2& building_b) const;

  /// The general search behind the three modes.
  LineMatchResult match(const std::vector<LineSegment2>& source,
                        const std::vector<LineSegment2>& target, const Pose2& guess, MatchMode mode,
                        bool rotation_unbounded = false) const;

  const LineMatcherParams& params() const { return params_; }

 private:
  LineMatcherParams params_;
};

/// The line matcher's information (§3.3.5: by feature type, scaled by fitness) rescaled so that
/// the best possible match (edge feature, full fitness) has the given standard deviations.
Eigen::Matrix3d scaledInformation(const Eigen::Matrix3d& matcher_info, double std_xy,
                                  double std_theta, const LineMatcherParams& m);

}  // namespace osm_graph_slam
