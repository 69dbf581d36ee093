#pragma once
// Scan Context place descriptor, implemented from the published idea (Kim & Kim, IROS 2018):
// a polar grid of rings x sectors around the sensor holding the maximum point height of each
// cell, a rotation-invariant ring key for fast retrieval, and a column-shift search that both
// compares two descriptors and recovers the yaw between them.
#include <Eigen/Core>

#include "osm_graph_slam/cloud/point_cloud.h"

namespace osm_graph_slam {

struct ScanContextParams {
  int num_rings = 20;           ///< radial bins
  int num_sectors = 60;         ///< azimuth bins (6 deg each by default)
  double max_radius = 80.0;     ///< [m] points farther away are ignored
  double min_radius = 1.0;      ///< [m] drops returns on the vehicle itself
  double sensor_height = 1.73;  ///< [m] above the ground: cell value = z + sensor_height (>= 0)
  double max_height = 30.0;     ///< [m] heights above this are clamped (trees, noise)
  double min_height = 0.3;      ///< [m] returns lower than this above the ground are ignored
  /// Columns searched either side of the sector-key pre-alignment; < 0 = try every shift.
  int sector_search_window = 3;
};

struct ScanContext {
  Eigen::MatrixXf cells;         ///< num_rings x num_sectors, max height (0 = empty)
  Eigen::VectorXf ring_key;      ///< per ring: fraction of occupied sectors (rotation invariant)
  Eigen::VectorXf sector_key;    ///< per sector: mean cell height (shifts with yaw)
  Eigen::VectorXf column_norms;  ///< cached L2 norm of each column
  int occupied_cells = 0;
};

struct ScanContextMatch {
  double distance = 1.0;  ///< 1 - mean column cosine similarity at the best shift, in [0, 1]
  int shift = 0;          ///< column shift applied to the candidate
  /// Yaw of the query sensor in the candidate sensor frame [rad] (p_cand = Rz(yaw) p_query).
  double yaw = 0.0;
};

/// The (ring, sector) cell of a sensor-frame point (x, y); false outside [min_radius, max_radius).
/// Shared by every descriptor built on this grid (LiDAR heights, radar powers).
bool scanContextCell(double x, double y, const ScanContextParams& params, int* ring, int* sector);
bool scanContextCell(float x, float y, const ScanContextParams& params, int* ring, int* sector);

/// Builds the descriptor of a cloud given in the sensor frame (non-finite points are skipped).
ScanContext computeScanContext(const PointCloud& cloud, const ScanContextParams& params);

/// The descriptor of stored cells (rings x sectors): the keys and norms recomputed (map packages).
ScanContext scanContextFromCells(const Eigen::MatrixXf& cells);

/// Distance of the two descriptors when candidate column (j + shift) is compared with query
/// column j; columns empty in both are ignored.
double scanContextDistanceAtShift(const ScanContext& query, const ScanContext& candidate,
                                  int shift);

/// Best column shift: sector-key pre-alignment then a local search (or every shift when
/// params.sector_search_window < 0).
ScanContextMatch matchScanContexts(const ScanContext& query, const ScanContext& candidate,
                                   const ScanContextParams& params);

/// Shift minimising the circular L1 difference of the sector keys.
int sectorKeyShift(const ScanContext& query, const ScanContext& candidate);

}  // namespace osm_graph_slam
