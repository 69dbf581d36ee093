#pragma once
// Parameters of the graph back-end, one slice per module (Cartographer-style nested options): each
// module receives only its slice. Every key is declared once, in its slice's visit() (key, field,
// one-line doc; common/param_declaration.h), every default once, in the field's initialiser;
// readParams() (slam/params_io.h), config/graph_backend*.yaml and config_consistency_test follow
// from them. The YAML keys are flat (a field's key is its name, or its slice's prefix + its name).
#include <string>

#include "osm_graph_slam/cloud/cloud_store_params.h"
#include "osm_graph_slam/cloud/occupancy_grid_params.h"
#include "osm_graph_slam/common/param_declaration.h"
#include "osm_graph_slam/graph/information.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/lines/line_matcher.h"
#include "osm_graph_slam/slam/building_contacts.h"
#include "osm_graph_slam/slam/sensor_inputs_params.h"

namespace osm_graph_slam {

/// OSM-SLAM modes (ART-SLAM §5.1.5-5.1.6).
enum class OsmMode {
  kPrior,    ///< buildings fixed: the map only corrects the robot
  kRigid,    ///< one global-match transform moves every building seen by a keyframe
  kNonRigid  ///< per-building local matching
};
const char* toString(OsmMode mode);
bool parseOsmMode(const std::string& text, OsmMode* mode);

/// Odometry edges (GraphBackend::addOdometryEdge), the attitude priors that keep the trajectory
/// level, and the odometry's scale.
struct OdometryEdgeParams {
  InformationParams information;
  /// Odometry edge to a keyframe the tracker re-anchored on a guess after failed matches: weak,
  /// so that loops, GNSS and OSM matches can correct the jump across the gap.
  double reanchor_std_xyz = 1.0;  ///< [m]
  double reanchor_std_rot = 0.1;  ///< [rad] roll, pitch and yaw
  // --- attitude (OSM priors say nothing about roll and pitch) ---
  double imu_attitude_std = 0.01;  ///< [rad] roll/pitch prior of keyframes with an IMU attitude
  /// [rad] without an IMU, keyframes with a map prior keep odometry's roll/pitch this firmly, so
  /// that planar priors are not satisfied by tilting the trajectory.
  double odometry_attitude_std = 0.02;
  // --- odometry scale (doc/backend.md "Odometry scale") ---
  /// One scale factor of the odometry's translations per odometry_scale_window metres of path,
  /// estimated with the trajectory (OSM, loops and GNSS observe it): a range bias of the LiDAR
  /// (e.g. a vertical-angle calibration error) makes scan matching a few tenths of a percent
  /// short or long, and without the factor the map evidence has to bend single steps instead.
  /// 0 = off (odometry edges as measured). Only the horizontal translation is scaled: a
  /// vertical drift held by the floor edges pulled a scale of all three axes (a 1.5 km drive
  /// without OSM got 23 % worse). 100 m with hessian_weight 0.0025 and prediction_error_scale 1:
  /// the real drive's map sharpness +5.4 % -> +0.9 % against the run without OSM, the drive
  /// matrix within -3.8 .. +0.7 % (doc/backend.md).
  double odometry_scale_window = 100.0;    ///< [m] of path per scale factor
  double odometry_scale_std = 0.01;        ///< prior deviation of the first factor from 1
  double odometry_scale_walk_std = 0.002;  ///< deviation of a factor from the previous window's

  template <class V>
  void visit(V& v) {
    InformationParams& i = information;
    v("odometry_min_std_xyz", i.min_std_xyz,
      "[m] odometry edge std at fitness 0 (squared into variances)");
    v("odometry_max_std_xyz", i.max_std_xyz,
      "[m] odometry edge std at fitness >= odometry_max_fitness: how far a poor scan match is "
      "trusted (ATE vs RPE, doc/backend.md)");
    v("odometry_min_std_rot", i.min_std_rot, "[rad] roll and pitch");
    v("odometry_max_std_rot", i.max_std_rot,
      "[rad] (larger: the floor edges bent a real drive without IMU, doc/backend.md)");
    v("odometry_min_std_yaw", i.min_std_yaw,
      "[rad] yaw: scan matching measures heading far better than the rest");
    v("odometry_max_std_yaw", i.max_std_yaw, "[rad]");
    v("odometry_max_fitness", i.max_fitness, "[m^2]");
    v("odometry_lateral_std_ratio", i.lateral_std_ratio,
      "translation std across the direction of motion / std along it");
    v("odometry_hessian_weight", i.hessian_weight,
      "+ this x the match's GICP Hessian (translation) as information (0: fitness model alone; "
      "doc/backend.md)");
    v("odometry_prediction_error_scale", i.prediction_error_scale,
      "translation covariance += (s e)(s e)^T, e = the match's offset from the motion model's "
      "prediction (0: off; doc/backend.md)");
    v("reanchor_std_xyz", reanchor_std_xyz,
      "[m] odometry edge to a keyframe re-anchored after a lost track");
    v("reanchor_std_rot", reanchor_std_rot, "[rad] (weak: loops, GNSS and OSM correct the jump)");
    v("imu_attitude_std", imu_attitude_std,
      "[rad] roll/pitch prior of keyframes with an IMU attitude");
    v("odometry_attitude_std", odometry_attitude_std,
      "[rad] without IMU: keyframes with a map prior keep odometry's roll/pitch");
    v("odometry_scale_window", odometry_scale_window,
      "[m] of path per estimated odometry scale factor, horizontal translation only (0: off; "
      "doc/backend.md \"Odometry scale\")");
    v("odometry_scale_std", odometry_scale_std, "prior deviation of the first factor from 1");
    v("odometry_scale_walk_std", odometry_scale_walk_std,
      "deviation of a factor from the previous window's");
  }
};

/// GNSS as evidence: position priors, their bias, the INS heading, and the first keyframe's anchor.
struct GnssParams {
  /// GNSS as evidence: [m] deviation of a position prior (level 0, Huber kernel) on every keyframe
  /// with a GNSS fix, and the first keyframe no longer fixed at its (noisy) fix but held by a
  /// prior on height, attitude and the known heading. 0 keeps the first keyframe fixed at its fix
  /// and uses no other fix. Needs a known initial heading (an IMU).
  double gnss_prior_std = 1.5;
  /// The fixes' robust kernel: huber, or cauchy, whose influence falls again beyond its width,
  /// so that a run of reflected (NLOS) fixes claiming a few metres' accuracy cannot pull a
  /// trajectory that odometry, loops and walls hold (doc/backend.md, GNSS priors).
  std::string gnss_prior_kernel = "cauchy";
  double gnss_prior_kernel_width = 2.0;  ///< kernel width in deviations
  /// A fix that reports its deviation σ (NavSatFix covariance, OXTS pos_accuracy) scales
  /// gnss_prior_std and gnss_bias_std together by σ / hypot(gnss_prior_std, gnss_bias_std): a
  /// receiver reports its whole error, bias included. RTK fixes then decide the absolute position
  /// and a shifted map cannot pull it; single-point fixes (σ ≈ 1.8 m) keep the deviations above.
  bool gnss_reported_accuracy = true;
  double gnss_min_reported_std = 0.05;  ///< [m] reported deviations below this count as this
  /// Innovation gate [deviations] (0: off): a fix farther from its keyframe's predicted position
  /// is not added. The prediction is the last optimisation's map -> odom applied to the
  /// keyframe's odometry; its deviation combines the fix's reported one, the GNSS error the
  /// estimate inherits (hypot(gnss_prior_std, gnss_bias_std)) and odometry's drift
  /// (gnss_gate_drift per metre) since the last fix that passed, so a run that lost its fixes
  /// for long takes them again. Reflected (NLOS) fixes claim metres of accuracy and lie by tens.
  double gnss_innovation_gate = 3.0;
  double gnss_gate_drift = 0.02;     ///< [m/m]
  double gnss_first_yaw_std = 0.01;  ///< [rad] the first keyframe's heading prior (INS)
  /// The fixes' slowly varying error (multipath, atmosphere, a consumer receiver's bias) as a
  /// first-order Gauss-Markov offset estimated with the trajectory: one XY bias vertex per
  /// gnss_bias_window seconds, [m] stationary deviation gnss_bias_std, correlation time
  /// gnss_bias_tau [s]; gnss_prior_std is then the fixes' white noise. Without it (0) every fix
  /// is independent and hundreds of them claim an absolute accuracy of a few centimetres that a
  /// 1 m bias does not have, so the trajectory follows the bias' wander and outvotes the map.
  double gnss_bias_std = 1.0;
  double gnss_bias_std_vertical = 1.5;  ///< [m] the bias' up component (with gnss_altitude_std)
  double gnss_bias_tau = 90.0;          ///< [s]
  double gnss_bias_window = 10.0;       ///< [s]
  /// [m] with GNSS priors: the fixes' altitude as evidence too, with this white-noise deviation
  /// (0: off, x and y only). The map origin is the first fix, whose altitude error (several
  /// metres for consumer GNSS) otherwise stays in every height; nothing else observes it.
  double gnss_altitude_std = 0.0;
  /// INS heading changes as evidence: [rad] the INS heading's noise per sample. Each keyframe
  /// with an INS orientation (KeyframeInput::ins_yaw) gets a yaw-difference edge (level 0, Huber)
  /// to the keyframe ins_heading_span metres back, so that the heading drifts with the INS's
  /// noise instead of the odometry's; the INS's constant bias cancels in the difference.
  /// 0 (default) = off; keep it off for magnetometer headings (local magnetic disturbances).
  double ins_heading_std = 0.0;
  double ins_heading_span = 100.0;        ///< [m] along the path
  double ins_heading_kernel_width = 2.0;  ///< Huber width in deviations
  /// The first keyframe (the map's anchor) held at its GNSS fix and known heading with these
  /// deviations instead of fixed there (height 5 cm, roll/pitch 0.01 rad), so that a trajectory
  /// the map prior disagrees with can shift and turn as a whole instead of bending; what the
  /// anchor's fix and the INS heading really know. 0 = fixed. Needs a known initial heading;
  /// with gnss_prior_std > 0 the fixes hold x and y and anchor_std_yaw is unused.
  /// anchor_std_xy is used when the fix does not report its deviation (KeyframeInput::gnss_std).
  double anchor_std_xy = 2.0;    ///< [m]
  double anchor_std_yaw = 0.01;  ///< [rad]

  template <class V>
  void visit(V& v) {
    v("gnss_prior_std", gnss_prior_std,
      "[m] GNSS position prior on every keyframe with a fix (0: off; the first keyframe is then "
      "fixed at its fix); needs a known initial heading (IMU)");
    v("gnss_prior_kernel", gnss_prior_kernel,
      "robust kernel of the GNSS priors (cauchy redescends: a fix far from what odometry, loops "
      "and walls hold loses its pull)",
      kKernelChoices);
    v("gnss_prior_kernel_width", gnss_prior_kernel_width,
      "width of the GNSS priors' kernel [deviations]");
    v("gnss_reported_accuracy", gnss_reported_accuracy,
      "a fix's reported deviation (NavSatFix covariance, OXTS pos_accuracy) scales gnss_prior_std "
      "and gnss_bias_std by it / their hypot (RTK fixes outweigh the map)");
    v("gnss_innovation_gate", gnss_innovation_gate,
      "[deviations] a fix farther than this from its keyframe's predicted position is not added "
      "(0: off; reflected fixes claim metres and lie by tens)");
    v("gnss_gate_drift", gnss_gate_drift,
      "[m/m] the prediction's growth per metre since the last fix that passed the gate");
    v("gnss_min_reported_std", gnss_min_reported_std,
      "[m] reported deviations below this count as this");
    v("gnss_first_yaw_std", gnss_first_yaw_std,
      "[rad] with GNSS priors: the first keyframe's heading prior (the INS heading)");
    v("gnss_bias_std", gnss_bias_std,
      "[m] with GNSS priors: the fixes' slowly varying bias, estimated (0: fixes independent; "
      "gnss_prior_std is then their white noise)");
    v("gnss_bias_std_vertical", gnss_bias_std_vertical,
      "[m] the GNSS bias' up component (used with gnss_altitude_std)");
    v("gnss_bias_tau", gnss_bias_tau,
      "[s] the GNSS bias' correlation time (first-order Gauss-Markov)");
    v("gnss_bias_window", gnss_bias_window, "[s] one GNSS bias estimate per window");
    v("gnss_altitude_std", gnss_altitude_std,
      "[m] with GNSS priors: the fixes' altitude as evidence too, white-noise deviation (0: x and "
      "y only; the first fix's altitude error then stays in every height)");
    v("ins_heading_std", ins_heading_std,
      "[rad] INS heading noise per sample: its changes over ins_heading_span tie the keyframes' "
      "headings (0: off; off for magnetometer headings)");
    v("ins_heading_span", ins_heading_span,
      "[m] each keyframe's INS heading change is taken from the keyframe this far back");
    v("ins_heading_kernel_width", ins_heading_kernel_width,
      "Huber width of the INS heading edges [deviations]");
    v("anchor_std_xy", anchor_std_xy,
      "[m] first keyframe held at its fix with this std instead of fixed (0: fixed; needs a known "
      "heading)");
    v("anchor_std_yaw", anchor_std_yaw,
      "[rad] ... and at the known heading with this std (0: fixed)");
  }
};

/// Floor edges (ART-SLAM §3.1.6): consecutive keyframes' floors are one plane, unless it bends.
struct FloorEdgeParams {
  bool floor_edges = true;           ///< plane-pair edges between keyframes with a floor
  double floor_normal_std = 0.005;   ///< [rad] of the floor normal (per keyframe)
  double floor_distance_std = 0.02;  ///< [m] of the floor's offset (per keyframe)
  double floor_kernel_width = 2.0;   ///< Huber width [deviations]
  /// Floors whose map-frame normals (through the current estimates) differ by more than this are
  /// a change of slope (a ramp, a crest, a kerb): no edge between them [deg].
  double floor_slope_change_deg = 1.5;
  /// Two floors further apart than this along the path are not tied (the road bends between) [m].
  double floor_max_link_distance = 10.0;
  /// Floor edges between keyframes that both have an IMU attitude also tie roll and pitch
  /// (false: only the height; gravity knows the attitude better than a floor fit).
  bool floor_attitude_with_imu = false;

  template <class V>
  void visit(V& v) {
    v("floor_edges", floor_edges,
      "plane-pair edges between consecutive keyframes with a floor (floor_detection)");
    v("floor_normal_std", floor_normal_std, "[rad] floor normal deviation per keyframe");
    v("floor_distance_std", floor_distance_std, "[m] floor offset deviation per keyframe");
    v("floor_kernel_width", floor_kernel_width, "Huber width of floor edges [deviations]");
    v("floor_slope_change_deg", floor_slope_change_deg,
      "[deg] floors whose map normals differ more: slope change, no edge");
    v("floor_max_link_distance", floor_max_link_distance,
      "[m] floors further apart along the path are not tied");
    v("floor_attitude_with_imu", floor_attitude_with_imu,
      "false: between keyframes with IMU attitude, floors tie the height only");
  }
};

/// Loop closure edges.
struct LoopEdgeParams {
  std::string loop_kernel = "cauchy";  ///< none | huber | cauchy
  double loop_kernel_width = 1.0;

  template <class V>
  void visit(V& v) {
    v("loop_kernel", loop_kernel, "robust kernel of loop edges", kKernelChoices);
    v("loop_kernel_width", loop_kernel_width, "the loop kernel's width [deviations]");
  }
};

/// OSM association (OsmAssociation): which buildings a keyframe is matched with, global and local
/// matching, and the robot<->building edges they give.
struct OsmAssociationParams {
  /// Buildings within this of a keyframe are matched [m]. Larger than the OSM buffer's 35 m
  /// queries on purpose: a building received when it came within 35 m of one keyframe is still
  /// matched from later keyframes up to 45 m away (more walls across the street; 60 s drive: ATE
  /// ratio 0.76 -> 0.65).
  double osm_query_radius = 45.0;
  double osm_max_wait = 10.0;     ///< [s] a keyframe waits this long for its buildings
  int min_keyframe_segments = 3;  ///< fewer segments: no OSM matching for that keyframe
  /// Global-matching priors on robot poses in non_rigid mode (prior and rigid modes always add
  /// them: they are how those modes use the map). One best alignment of every nearby building
  /// is biased when the buildings are misplaced independently, and the same misplaced buildings
  /// then pull every keyframe that sees them; non_rigid mode with joint_optimization gets the
  /// map's absolute information from the building priors instead (each building counted once).
  /// Global matching still sets the initial heading when it is unknown.
  bool use_global_priors = false;
  double global_min_fitness = -20.0;  ///< global matches below this add no prior
  int global_min_matched = 3;
  /// Standard deviations of a global-matching prior on a robot pose for the best possible match
  /// (an edge feature at full fitness); weaker matches get proportionally less information and
  /// a single visible wall constrains only its normal (§3.3.5). They should reflect how well the
  /// OSM map itself is registered: a prior from misplaced buildings is only as good as they are.
  double global_prior_std_xy = 0.5;    ///< [m]
  double global_prior_std_yaw = 0.02;  ///< [rad]
  /// Local matches below this add no building edge. A correct match often leaves some visible
  /// walls unmatched (parked cars, trees, range): -50 as the matcher's own limit.
  double local_min_fitness = -50.0;
  /// One matched wall is enough: a lone facade still fixes the building across the street (the
  /// edge then constrains only that direction, §3.3.5); with 2, two thirds of the correct
  /// matches on the simulated Karlsruhe drive were thrown away.
  int local_min_matched = 1;
  /// Local matching aligns only the walls the keyframe can see (facing it, within
  /// osm_query_radius, not hidden behind other buildings): unseen walls otherwise count as
  /// unmatched and push the fitness of every correct match far below local_min_fitness.
  bool local_visible_walls_only = true;
  int local_min_visible_walls = 1;
  /// Robust kernel of robot<->building edges (a wall matched to the neighbour's wall).
  std::string building_edge_kernel = "cauchy";  ///< none | huber | cauchy
  double building_edge_kernel_width = 2.0;
  /// Robot↔building edge standard deviations for the best possible local match (same scaling).
  double local_edge_std_xy = 0.3;      ///< [m]
  double local_edge_std_theta = 0.03;  ///< [rad]
  /// [m] of path between two edges on the same building: consecutive keyframes see a wall with
  /// the same errors (motion distortion, calibration), so their edges are not independent
  /// evidence. 0 = an edge from every keyframe.
  double building_edge_spacing = 0.0;
  /// true: the edge's information is taken where the matched walls are and carried to the
  /// building's reference vertex with the rotation's lever arm. false: as if the vertex itself
  /// had been matched, although it can be 20 m from the walls that were seen (doc/backend.md).
  bool local_edge_at_walls = true;

  template <class V>
  void visit(V& v) {
    v("osm_query_radius", osm_query_radius,
      "[m] buildings received (osm_buffer: within 35 m of some pose) and within this of a keyframe "
      "are matched");
    v("osm_max_wait", osm_max_wait, "[s] a keyframe waits this long for its buildings / segments");
    v("min_keyframe_segments", min_keyframe_segments,
      "fewer wall segments: no OSM matching for the keyframe");
    v("use_global_priors", use_global_priors,
      "global-matching priors on robots (biased when buildings are misplaced one by one); heading "
      "init always");
    v("global_min_fitness", global_min_fitness, "global matches below this fitness add no prior");
    v("global_min_matched", global_min_matched, "... or with fewer matched segments");
    v("global_prior_std_xy", global_prior_std_xy,
      "[m] prior std for the best possible global match (weaker ones scale down)");
    v("global_prior_std_yaw", global_prior_std_yaw, "[rad]");
    v("local_min_fitness", local_min_fitness,
      "local (per-building) matches below this add no edge (unmatched visible walls are common)");
    v("local_min_matched", local_min_matched,
      "one matched facade suffices (its edge constrains only its normal)");
    v("local_visible_walls_only", local_visible_walls_only,
      "local matching aligns only walls facing the keyframe, in range, not hidden by other "
      "buildings");
    v("local_min_visible_walls", local_min_visible_walls,
      "buildings with fewer visible walls are not matched");
    v("building_edge_kernel", building_edge_kernel,
      "robust kernel of robot<->building edges (wrong wall associations)", kKernelChoices);
    v("building_edge_kernel_width", building_edge_kernel_width,
      "the building edge kernel's width [deviations]");
    v("local_edge_std_xy", local_edge_std_xy,
      "[m] robot<->building edge std for the best possible local match");
    v("local_edge_std_theta", local_edge_std_theta, "[rad]");
    v("building_edge_spacing", building_edge_spacing,
      "[m] of path between two edges on one building (consecutive views share their errors; 0: "
      "every keyframe)");
    v("local_edge_at_walls", local_edge_at_walls,
      "edge information taken at the matched walls, carried to the building vertex (false: at the "
      "vertex; doc/backend.md)");
  }
};

/// The OSM map as a prior: each building's prior, the OSM datum they are relative to, and the
/// re-association after the datum moved (BackendState's building vertices, OsmAssociation).
struct OsmPriorParams {
  /// OSM prior of each building, relative to the datum, with GNSS priors holding the trajectory
  /// (about one building's misplacement in OSM): the map's common position then counts against
  /// the fixes' (doc/backend.md, default matrix).
  double building_prior_std_xy = 1.5;  ///< [m]
  /// ... when fewer than two fixes hold the run (GNSS priors off, no known heading, one origin):
  /// deliberately weak, so a building follows its observations and a misplaced map cannot pull
  /// the one anchor (1 m gave +34 % on a 60 s Karlsruhe drive).
  double building_prior_std_xy_without_gnss = 5.0;  ///< [m]
  double building_prior_std_theta = 0.1;            ///< [rad]
  /// OSM datum (doc/backend.md "Why the prior hurt"): > 0 ties every building's prior to one
  /// SE2 vertex, the offset of the OSM map as a whole, held at zero with these deviations, so a
  /// map that is shifted as a whole (imagery offsets, another datum) does not drag the trajectory
  /// away from its GNSS anchor; only each building's deviation from the common offset does.
  /// 0 = off (every prior absolute, as in the thesis).
  double osm_datum_std_xy = 1.5;     ///< [m]
  double osm_datum_std_theta = 0.0;  ///< [rad] (0 with the datum on: translation only)
  /// Robust kernel of the datum's prior (none | huber | cauchy): a tight deviation for maps that
  /// agree with the GNSS evidence, released for one shifted far beyond it.
  std::string osm_datum_kernel = "cauchy";
  double osm_datum_kernel_width = 1.0;  ///< [deviations]
  /// ... when only the first fix anchors the run. Looser than with fixes: the real OSM of KITTI
  /// 0005 is 3.6 m off its RTK first fix, and 1.5 m with Cauchy turned that drive about its
  /// anchor (walls 0.28 -> 0.54 m) while helping only simulated maps with no common offset
  /// (doc/backend.md, 'Without GNSS').
  double osm_datum_std_xy_without_gnss = 3.0;          ///< [m]
  std::string osm_datum_kernel_without_gnss = "none";  ///< ... and its kernel
  /// [m] keyframes matched while the datum was this far from its current estimate are matched
  /// again (their walls were paired at the map's stale position). 0 = never. With GNSS priors
  /// the datum is learnt against the fixes and wanders by tenths of a metre: 0.5 m re-matched
  /// 2.2x the keyframes (+38 % back-end time at 1.5 km) for no accuracy (doc/backend.md). With
  /// one anchor the datum travels metres (real drive: 3.4 m) and the finer re-association is
  /// what keeps the walls aligned.
  double osm_datum_reassociate_distance = 1.0;
  double osm_datum_reassociate_distance_without_gnss = 0.5;  ///< [m]
  /// true: a building no keyframe observed keeps its OSM prior (shared walls tie only observed
  /// pairs; overlap resolution moves the observed building, both when neither was observed).
  /// false (default): it follows the observed neighbour it shares a wall with. Measured on the
  /// quick matrix, true made the observed buildings worse (0.680 -> 1.186 m, Karlsruhe): overlap
  /// edges then push them off the unobserved neighbours' wrong priors (doc/backend.md).
  bool unobserved_buildings_fixed = false;

  template <class V>
  void visit(V& v) {
    v("building_prior_std_xy", building_prior_std_xy,
      "[m] OSM prior edge of every building (level 1) when GNSS priors hold the run "
      "(doc/backend.md)");
    v("building_prior_std_xy_without_gnss", building_prior_std_xy_without_gnss,
      "[m] the building priors when only the first fix anchors the run: weak on purpose, a "
      "misplaced map must not pull the one anchor");
    v("building_prior_std_theta", building_prior_std_theta, "[rad] the building priors' heading");
    v("osm_datum_std_xy", osm_datum_std_xy,
      "[m] > 0: building priors relative to one OSM-map offset vertex held at 0 with this std (0: "
      "absolute priors)");
    v("osm_datum_std_theta", osm_datum_std_theta,
      "[rad] the datum's rotation (0: translation only)");
    v("osm_datum_kernel", osm_datum_kernel,
      "robust kernel of the datum's prior (a map shifted far beyond the fixes is let go)",
      kKernelChoices);
    v("osm_datum_kernel_width", osm_datum_kernel_width, "the datum kernel's width [deviations]");
    v("osm_datum_std_xy_without_gnss", osm_datum_std_xy_without_gnss,
      "[m] the datum when only the first fix anchors the run");
    v("osm_datum_kernel_without_gnss", osm_datum_kernel_without_gnss,
      "the datum's kernel when only the first fix anchors the run", kKernelChoices);
    v("osm_datum_reassociate_distance", osm_datum_reassociate_distance,
      "[m] keyframes matched while the datum was this far from its estimate are matched again, "
      "GNSS priors holding the run (0: never; doc/backend.md)");
    v("osm_datum_reassociate_distance_without_gnss", osm_datum_reassociate_distance_without_gnss,
      "[m] ... when only the first fix anchors it (the datum travels metres)");
    v("unobserved_buildings_fixed", unobserved_buildings_fixed,
      "true: a building no keyframe observed keeps its OSM prior (worse for the observed ones, "
      "doc/backend.md)");
  }
};

/// Building<->building constraints (BuildingConstraints): the χ² gate on robot<->building edges,
/// shared walls and overlap resolution (OSM thesis Alg. 3.2).
struct BuildingConstraintParams {
  /// After phase 2, robot<->building edges whose error against the building's estimate exceeds
  /// this chi2 (3 DOF; 9 = 97 %) are removed for good (0: keep every edge).
  double building_edge_gate_chi2 = 9.0;
  bool resolve_overlaps = true;
  int overlap_max_iterations = 15;
  double overlap_information = 1e6;  ///< hard building↔building constraints (§3.5)
  double overlap_min_area = 0.05;    ///< [m^2] smaller intersections are touching walls
  /// [m] separated buildings are placed this much further apart than flush, so that buildings
  /// separated from two neighbours at once do not end overlapping by a compromise of millimetres.
  double overlap_clearance = 0.01;
  /// [m] Overlaps the hard edges leave (a building wedged between two neighbours whose edges
  /// push it back and forth) are cleared by moving the less observed building by the shortest
  /// translation that frees it, at most this far (0 = off; doc/backend.md).
  double overlap_projection_max_translation = 0.5;
  /// Non-rigid mode: buildings whose facing walls (nearly) coincide in the prior keep them
  /// coinciding (two wall-end-on-wall edges per pair, level 1, Huber kernel). A building seen
  /// through one facade is then placed along its street by the neighbours it touches, and a
  /// building nobody saw follows an observed neighbour. doc/backend.md "Shared walls".
  bool use_shared_walls = true;
  double shared_wall_std = 0.2;           ///< [m] distance of each wall end from the other wall
  double shared_wall_kernel_width = 1.0;  ///< Huber width in standard deviations
  BuildingContactParams shared_walls;

  template <class V>
  void visit(V& v) {
    v("building_edge_gate_chi2", building_edge_gate_chi2,
      "after phase 2, building edges above this chi2 (3 DOF, 97 %) are removed; 0 = off");
    v("resolve_overlaps", resolve_overlaps, "overlap resolution, OSM thesis Alg. 3.2 (level 2)");
    v("overlap_max_iterations", overlap_max_iterations, "rounds of hard edges and optimisation");
    v("overlap_information", overlap_information, "hard building<->building constraints");
    v("overlap_min_area", overlap_min_area, "[m^2] smaller intersections are touching walls");
    v("overlap_clearance", overlap_clearance,
      "[m] separated buildings end this far apart (not flush; doc/backend.md)");
    v("overlap_projection_max_translation", overlap_projection_max_translation,
      "[m] overlaps the hard edges leave: the less observed building moves by the shortest "
      "translation that clears it, at most this far (0: off)");
    v("use_shared_walls", use_shared_walls,
      "non_rigid: buildings whose facing walls coincide in the prior keep them coinciding (off for "
      "detached houses a few metres apart)");
    v("shared_wall_std", shared_wall_std,
      "[m] each wall end from the neighbour's wall (level 1 edges)");
    v("shared_wall_kernel_width", shared_wall_kernel_width, "Huber width in standard deviations");
    v("shared_wall_max_distance", shared_walls.max_distance,
      "[m] gap or overlap in the prior still counted as shared: real OSM neighbours share nodes "
      "(config/sim.yaml: 2.5)");
    v("shared_wall_max_angle_deg", shared_walls.max_angle_deg,
      "facing walls antiparallel within this");
    v("shared_wall_min_fraction", shared_walls.min_shared_fraction,
      "they face each other over this fraction of the shorter wall ...");
    v("shared_wall_min_length", shared_walls.min_shared_length, "[m] ... or over this length");
  }
};

/// When and how the graph is optimised (GraphBackend::optimizePhases).
struct OptimizationScheduleParams {
  /// Every optimize() call (phase 1, phase 2, overlaps); read below "graph_optimizer/" by
  /// readParams(OptimizerOptions).
  OptimizerOptions optimizer;
  /// Bounded cost while driving (doc/backend.md "Windowed updates"): > 0 frees only the newest
  /// this many keyframes, and the buildings they observe, in a routine update; older keyframes
  /// and other buildings are held where the last full batch left them. A forced update
  /// (save_map, dump_graph, the end of an offline run) is always a full batch. 0 = every update
  /// is a full batch (its cost grows with the graph).
  int optimization_window = 300;
  /// A loop from the window to a held keyframe that still disagrees by more than this χ² (6 dof)
  /// after the windowed update calls for a full batch: the window cannot absorb the drift the
  /// loop reveals. ≤ 0: never (full batches only when forced).
  double window_loop_chi2 = 16.8;
  /// Phase 3: robots and buildings together (levels 0-1, first keyframe fixed), so that the
  /// building priors correct the trajectory's drift; false = the thesis' two phases only.
  bool joint_optimization = true;
  /// Odometry information in the joint phase relative to phase 1 (1: the same).
  double joint_odometry_weight = 1.0;

  template <class V>
  void visit(V& v) {
    v("optimization_window", optimization_window,
      "routine updates free only the newest N keyframes (and the buildings they see), older held; "
      "save_map/dump/end of run: full batch (0: always full batch; doc/backend.md \"Windowed "
      "updates\")");
    v("window_loop_chi2", window_loop_chi2,
      "a new loop to a held keyframe that still disagrees by more than this chi2 (6 dof) after the "
      "window calls a full batch (<= 0: never)");
    v("joint_optimization", joint_optimization,
      "phase 3: robots + buildings together, building priors correct drift");
    v("joint_odometry_weight", joint_odometry_weight,
      "odometry information in phase 3 relative to phase 1 (stiffer: smoother corrections)");
  }
};

/// The back-end's parameters: the mode, the initial pose, and one slice per module.
struct GraphBackendParams {
  bool use_osm = true;
  OsmMode mode = OsmMode::kNonRigid;
  /// The first keyframe is fixed at the map origin (the first GPS fix); its heading comes from
  /// the first global matching with unbounded rotation (§3.4) unless initial_yaw_known.
  bool initial_yaw_known = false;
  double initial_yaw = 0.0;  ///< [rad] ENU yaw of the first keyframe when known
  SensorInputsParams inputs;
  OdometryEdgeParams odometry;
  GnssParams gnss;
  FloorEdgeParams floor;
  LoopEdgeParams loops;
  OsmAssociationParams association;
  OsmPriorParams osm_prior;
  BuildingConstraintParams buildings;
  OptimizationScheduleParams schedule;
  LineMatcherParams matcher;  ///< read below "line_matcher/" by readParams(LineMatcherParams)
  /// Not the graph's: the 2-D grid rendered from its keyframes (slam/grid_map.h), kept here so
  /// that save_map, the nodelet and the offline runners read it with the back-end's keys.
  OccupancyGridParams grid;
  /// Not the graph's either: where the keyframes' clouds are kept (compressed, spilled to disk
  /// beyond a memory budget) for loops, map export, save_map and the grid.
  /// Lossless: the saved map and the localiser's learnt limits are what they were with PCL
  /// clouds (at 1 cm a single impostor in the localisation rostest's map passed the fitness test
  /// and raised the learnt overlap limit from 0.6 to 0.83; doc/long_drives.md).
  CloudStoreParams cloud_store = [] {
    CloudStoreParams p;
    p.codec.resolution = 0.0;
    return p;
  }();

  /// The keys of this level but "mode" (an enum, read by readParams()).
  template <class V>
  void visit(V& v) {
    v("use_osm", use_osm, "false: odometry + loops only (the baseline)");
    v("initial_yaw_known", initial_yaw_known,
      "true: first keyframe heading = initial_yaw; false: from global matching");
    v("initial_yaw", initial_yaw, "[rad] ENU yaw of the first keyframe when known");
  }
  /// visit() and every slice's keys: every flat key of the back-end but "mode" (line_matcher/
  /// and graph_optimizer/ have their own readers).
  template <class V>
  void visitAll(V& v) {
    visit(v);
    inputs.visit(v);
    odometry.visit(v);
    gnss.visit(v);
    floor.visit(v);
    loops.visit(v);
    association.visit(v);
    osm_prior.visit(v);
    buildings.visit(v);
    schedule.visit(v);
    grid.visit(v);
    cloud_store.visit(v);
  }
};

}  // namespace osm_graph_slam
