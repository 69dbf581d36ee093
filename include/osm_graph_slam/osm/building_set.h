#pragma once
// Properties of a set of buildings used by the back-end (overlap resolution, saved maps) and by
// the evaluation alike.
#include <utility>
#include <vector>

#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

/// Tag the back-end puts on each corrected building: its number of robot<->building edges.
inline constexpr const char* kObservationsTag = "osm_graph_slam:observations";
/// ... the number of keyframes those edges come from, and of sessions (drives).
inline constexpr const char* kKeyframesTag = "osm_graph_slam:keyframes";
inline constexpr const char* kSessionsTag = "osm_graph_slam:drives";
/// ... the estimate's marginal deviations: position [m] (the larger axis), heading [deg].
inline constexpr const char* kSigmaXyTag = "osm_graph_slam:sigma_xy";
inline constexpr const char* kSigmaThetaTag = "osm_graph_slam:sigma_heading_deg";

/// Pairs of buildings whose outlines intersect with more than min_area [m^2] (shared walls of
/// touching buildings have zero area and are not counted).
std::vector<std::pair<size_t, size_t>> findOverlappingBuildings(
    const std::vector<Building>& buildings, double min_area = 0.05);

/// Whether OSM says the outline is a roof on open sides (`building=roof` or `carport`, or
/// `building:walls=no`): a tram shelter, a petrol-station canopy. Its outline edges are not walls.
bool isRoofOnly(const Building& building);

}  // namespace osm_graph_slam
