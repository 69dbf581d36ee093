#pragma once
// Reading and writing the g2o text format (the format of the public pose-graph datasets).
//
// Supported tags: VERTEX_SE2, EDGE_SE2, VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_XY, EDGE_SE2_XY,
// EDGE_PRIOR_SE2, FIX. Information matrices are stored as their upper triangle, row by row.
// Vertices referenced by edges but never declared (edge-only files such as M3500) are
// initialised by composing the odometry chain (edges between consecutive ids), then by a
// breadth-first walk over the remaining edges.
#include <Eigen/Core>
#include <iosfwd>
#include <string>
#include <vector>

#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam {

/// How to read a file.
struct G2oReadOptions {
  /// An edge whose information matrix is indefinite (some public datasets have one, e.g.
  /// cubicle.g2o) is refused unless this is set; then the matrix is replaced by the nearest
  /// positive semi-definite matrix in the Frobenius norm (negative eigenvalues set to 0, Higham
  /// 1988) and the repair is counted and listed in the result.
  bool repair_information = false;
};

/// One information matrix replaced by G2oReadOptions::repair_information.
struct G2oInformationRepair {
  int line = 0;                   ///< 1-based line of the edge
  double min_eigenvalue = 0.0;    ///< smallest eigenvalue before the repair (< 0)
  double frobenius_change = 0.0;  ///< ||repaired - original||_F
};

struct G2oReadResult {
  bool ok = false;
  int line = 0;         ///< 1-based line of the first error (0: not tied to a line)
  std::string message;  ///< "line N: ..." on error
  int num_vertices = 0;
  int num_edges = 0;
  int num_fixed = 0;
  int num_initialised = 0;           ///< vertices not declared in the file, initialised from edges
  int num_repaired_information = 0;  ///< information matrices projected (repair_information)
  std::vector<G2oInformationRepair> repairs;  ///< one per repaired edge, in file order
};

/// Reads a graph. On error the output graph is left untouched (nothing is half-read).
G2oReadResult readG2o(const std::string& path, PoseGraph* graph,
                      const G2oReadOptions& options = {});
G2oReadResult readG2o(std::istream& in, PoseGraph* graph, const G2oReadOptions& options = {});

/// The nearest positive semi-definite matrix to the symmetric matrix information (Frobenius
/// norm): its eigen-decomposition with the negative eigenvalues set to 0. Returns false (and
/// leaves *repaired alone) when information already is positive semi-definite within the
/// tolerance PoseGraph uses; *min_eigenvalue gets the smallest eigenvalue either way.
bool nearestPositiveSemiDefinite(const Eigen::MatrixXd& information, Eigen::MatrixXd* repaired,
                                 double* min_eigenvalue = nullptr);

struct G2oWriteResult {
  bool ok = false;
  std::string message;
  int num_vertices = 0;
  int num_edges = 0;
  int num_skipped_edges = 0;     ///< edge types the g2o format above cannot express (SE3 priors...)
  int num_skipped_vertices = 0;  ///< vertex types it cannot express (scales)
};

/// Writes every vertex, FIX lines for fixed vertices and every expressible edge, with 17
/// significant digits (exact round trip). A scaled SE3 edge is written as an SE3 edge whose
/// translation is multiplied by its scale vertex's estimate; scale vertices are skipped. The file
/// is written to a temp file, then renamed.
G2oWriteResult writeG2o(const PoseGraph& graph, const std::string& path);
G2oWriteResult writeG2o(const PoseGraph& graph, std::ostream& out);

}  // namespace osm_graph_slam
