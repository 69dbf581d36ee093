#pragma once
// OSM association (OSM thesis §3.3-3.4): for each keyframe whose walls and buildings have
// arrived, global matching (initial heading, robot priors, rigid mode's one transform) and, in
// non_rigid mode, local matching of each nearby building: the robot<->building edges.
// Internal to src/slam/.
#include <vector>

#include "backend_state.h"

namespace osm_graph_slam {

class OsmAssociation {
 public:
  /// joint_optimization and odometry_attitude_std: without an IMU, a keyframe with a building
  /// edge gets an attitude prior for the joint phase (OdometryEdgeParams).
  OsmAssociation(OsmMode mode, const OsmAssociationParams& params, const OsmPriorParams& prior,
                 const LineMatcherParams& matcher, bool joint_optimization,
                 double odometry_attitude_std, const Logger& logger)
      : mode_(mode),
        params_(params),
        prior_(prior),
        joint_optimization_(joint_optimization),
        odometry_attitude_std_(odometry_attitude_std),
        logger_(logger),
        matcher_(matcher) {}

  /// Associates every keyframe that is ready and not yet processed.
  void process(BackendState& s, BackendUpdateReport& report) const;

  /// Keyframes matched while the OSM datum was more than osm_datum_reassociate_distance from
  /// where it is now lose their building edges and are matched again by the next process().
  size_t reassociateAfterDatumMoved(BackendState& s, BackendUpdateReport& report) const;

 private:
  struct Neighbourhood {
    std::vector<BuildingState*> buildings;
    std::vector<LineSegment2> segments;  ///< their prior walls (map)
  };
  /// Whether the keyframe's segments and buildings are there; gives up once it is too old.
  bool ready(const BackendState& s, uint64_t id, KeyframeState& kf) const;
  Neighbourhood nearby(BackendState& s, const Pose2& robot) const;
  /// Rotates the trajectory to the heading of the first accepted unbounded global match.
  void initializeHeading(BackendState& s, uint64_t id, const Pose2& robot,
                         const LineMatchResult& global, BackendUpdateReport& report) const;
  void addRigidEdges(BackendState& s, uint64_t id, const Neighbourhood& near,
                     const LineMatchResult& global, BackendUpdateReport& report) const;
  void addNonRigidEdges(BackendState& s, uint64_t id, KeyframeState& kf, const Neighbourhood& near,
                        const Pose2& observed_from, BackendUpdateReport& report) const;
  /// The walls of b (outline: its current estimate) that the keyframe can see past the
  /// occluders (all walls unless visibility is on); empty when too few are visible.
  std::vector<LineSegment2> visibleWallsOf(const BuildingState& b, const Polygon2& outline,
                                           const std::vector<const Polygon2*>& occluders,
                                           const Pose2& observed_from) const;
  void addLocalEdge(BackendState& s, uint64_t id, KeyframeState& kf, BuildingState& b,
                    const Pose2& observed_from, const LineMatchResult& local,
                    BackendUpdateReport& report) const;
  void addGlobalPrior(BackendState& s, KeyframeState& kf, const LineMatchResult& global) const;
  void addOdometryAttitudePrior(BackendState& s, KeyframeState& kf, int level) const;
  Eigen::Matrix3d localInformation(const LineMatchResult& match) const;

  const OsmMode mode_;
  const OsmAssociationParams& params_;
  const OsmPriorParams& prior_;
  const bool joint_optimization_;
  const double odometry_attitude_std_;
  const Logger& logger_;
  LineMatcher matcher_;
};

}  // namespace osm_graph_slam
