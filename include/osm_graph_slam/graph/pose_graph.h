#pragma once
// A g2o-style pose graph solved with Ceres: SE3 robot keyframes, SE2 buildings, XY points, edges
// with information matrices, robust kernels and optimisation levels (OSM thesis §3.4). This
// header is Ceres-free on purpose (it is included by the back-end, nodelets and tools); the cost
// functions and manifolds live in src/graph/.
//
// Error conventions follow g2o so that χ² = Σ eᵀΩe is comparable with g2o and the .g2o datasets:
//   SE2 edge   e = toVector(Z⁻¹ · (Xi⁻¹ Xj))            = (x, y, wrapped θ)
//   SE3 edge   e = (t, qx, qy, qz) of Z⁻¹ · (Xi⁻¹ Xj)  with the quaternion sign chosen so qw ≥ 0
//   priors     the same with Xi = identity; point edges e = Xi⁻¹ p − z.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <climits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// kScale: one positive factor (e.g. the odometry's scale over a stretch of the drive).
enum class VertexType { kSE3, kSE2, kPointXY, kPointXYZ, kScale };

enum class EdgeType {
  kSE3,          ///< SE3–SE3 relative pose (6×6 information)
  kSE2,          ///< SE2–SE2 relative pose (3×3)
  kSE3SE2,       ///< SE3 robot projected to (x, y, yaw) against an SE2 building (3×3)
  kPriorSE3,     ///< unary full SE3 pose (6×6)
  kPriorSE3XY,   ///< unary SE3 position x, y (2×2), e.g. GPS without altitude
  kPriorSE3XYZ,  ///< unary SE3 position x, y, z (3×3)
  kPriorSE3Yaw,  ///< unary SE3 yaw (1×1), e.g. a heading from global matching
  kPriorSE2,     ///< unary full SE2 pose (3×3), e.g. the OSM prior of a building
  kSE2PointXY,   ///< SE2 pose observes an XY point in its frame (2×2)
  kSE3PointXY,   ///< SE3 pose (projected to the plane) observes an XY point (2×2)
  /// A point fixed in the first SE2 vertex lies on a line fixed in the second (1×1), e.g. the end
  /// of a building's wall on the wall it shares with its neighbour.
  kSE2PointOnLine,
  /// Two SE3 poses stand on one plane (e.g. the floor, ART-SLAM §3.1.6): the plane measured in
  /// the first frame, carried into the second by the estimates, must be the plane measured there
  /// (3×3: the normal's x and y, the offset).
  kSE3PlanePair,
  kPriorPointXYZ,  ///< unary XYZ point (3×3)
  /// First-order Gauss-Markov process between two XYZ points (3×3): e = b₂ − φ·b₁, measurement
  /// φ = exp(−Δt/τ); e.g. the drift of a GNSS bias.
  kPointXYZGaussMarkov,
  /// SE3 position plus an XYZ offset (3×3): e = p + b − z, e.g. a GNSS fix with its bias (a fix
  /// without altitude: the information's z row and column 0).
  kSE3PositionWithOffset,
  /// Yaw change between two SE3 poses (1×1): e = wrap(yaw(Xto) − yaw(Xfrom) − z), e.g. an INS's
  /// heading change, whose constant bias cancels.
  kSE3YawDifference,
  /// SE3–SE3 relative pose whose measured translation is multiplied by a kScale vertex (third
  /// vertex; 6×6 information as kSE3): e = log((R_z, S·t_z)⁻¹ · Xfrom⁻¹ Xto) with S = diag(s, s,
  /// 1): odometry whose scale is estimated. Only the horizontal part (x, y in the from-frame) is
  /// scaled: a vertical drift of the odometry is no scale error, and the floor edges that hold
  /// the height must not pull the scale with it.
  kSE3Scaled,
  kPriorScale,       ///< unary kScale (1×1): e = s − z
  kScaleDifference,  ///< two kScale vertices (1×1): e = s_to − s_from − z (a random walk)
};

/// The most vertices an edge connects.
constexpr int kMaxEdgeVertices = 3;

const char* toString(VertexType type);
const char* toString(EdgeType type);
/// Dimension of the error vector (= size of the information matrix) of an edge type.
int errorDimension(EdgeType type);
/// Length of the measurement vector of an edge type (see EdgeInfo::measurement).
int measurementDimension(EdgeType type);

enum class RobustKernelType { kNone, kHuber, kCauchy };

/// g2o semantics: Huber ρ(s) = s for √s ≤ width, else 2·width·√s − width²;
/// Cauchy ρ(s) = width²·log(1 + s/width²), with s = eᵀΩe.
struct RobustKernel {
  RobustKernelType type = RobustKernelType::kNone;
  double width = 1.0;

  static RobustKernel none() { return {}; }
  static RobustKernel huber(double w) { return {RobustKernelType::kHuber, w}; }
  static RobustKernel cauchy(double w) { return {RobustKernelType::kCauchy, w}; }
};

struct EdgeOptions {
  int level = 0;  ///< optimisation level (≥ 0): optimize(n) uses every edge with level ≤ n
  RobustKernel kernel;
};

/// A read-only view of one edge.
struct EdgeInfo {
  int id = -1;
  EdgeType type = EdgeType::kSE2;
  std::vector<int> vertices;  ///< one (priors) or two vertex ids, in the order of the add call
  int level = 0;
  RobustKernel kernel;
  /// SE3: (tx, ty, tz, qx, qy, qz, qw); SE2/SE3SE2/PriorSE2: (x, y, θ); XY/point: (x, y);
  /// XYZ: (x, y, z); yaw: (yaw); point-on-line: (px, py, nx, ny, c), see addEdgeSE2PointOnLine();
  /// plane pair: (a, b, c, d) in the first frame, then in the second, see addEdgeSE3PlanePair().
  Eigen::VectorXd measurement;
  Eigen::MatrixXd information;
};

enum class TerminationReason {
  kConverged,       ///< a Ceres tolerance was met
  kMaxIterations,   ///< stopped at max_iterations (result usable, maybe not converged)
  kNothingToSolve,  ///< no active edge, or every active vertex fixed
  kFailure,         ///< Ceres failed (e.g. numerical failure); vertices keep their last values
};
const char* toString(TerminationReason reason);

/// Sparse Cholesky back-end of Ceres' SPARSE_NORMAL_CHOLESKY solver.
enum class SparseLibrary { kAuto, kSuiteSparse, kEigenSparse };

struct OptimizerOptions {
  int max_iterations = 100;
  double function_tolerance = 1e-6;  ///< Ceres relative cost-change tolerance
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  int num_threads = 1;  ///< residual/Jacobian evaluation threads
  /// auto: Eigen's simplicial Cholesky for problems of at most auto_eigen_max_free_vertices free
  /// vertices, SuiteSparse's supernodal one (when Ceres has it) for larger ones. Measured
  /// (doc/backend.md): Eigen 0.74-0.93x the back-end time of the 1.5 km drives
  /// (windows of 300 keyframes, full batches of 800), but 1.42x on sphere2500 and 1.58x on a
  /// full batch of 4,000 keyframes with a loop at each.
  SparseLibrary sparse_library = SparseLibrary::kAuto;
  int auto_eigen_max_free_vertices = 2000;
  /// Levenberg–Marquardt starting radius. Large (nearly Gauss–Newton first steps) suits pose
  /// graphs: 3–7 iterations on the public datasets instead of 7–29 with Ceres' default 1e4;
  /// rejected steps shrink it quickly when the start is poor.
  double initial_trust_region_radius = 1e12;
  /// Closed-form Jacobians for SE2 and SE3 edges (fast). false: automatic differentiation of the
  /// same error (kept as a cross-check).
  bool analytic_jacobians = true;
  /// Leave out edges whose vertices are all fixed: their cost cannot change, so the solution is
  /// the same, but a graph that is mostly fixed (a sliding window) is set up and evaluated in
  /// time of its free part. χ² in the result then covers only the edges kept.
  bool skip_constant_edges = false;
  bool verbose = false;  ///< fill OptimizationResult::report with Ceres' full report
};

struct OptimizationResult {
  bool success = false;  ///< the vertices hold a usable solution (converged or max iterations)
  TerminationReason termination = TerminationReason::kFailure;
  std::string message;        ///< Ceres' termination message or the reason nothing was solved
  double initial_chi2 = 0.0;  ///< Σ eᵀΩe of the active edges before (no robust kernel)
  double final_chi2 = 0.0;    ///< ... and after
  int iterations = 0;         ///< Levenberg–Marquardt iterations (successful + rejected steps)
  double time_ms = 0.0;       ///< total wall time: problem set-up, χ², solve
  double solve_ms = 0.0;      ///< wall time of ceres::Solve only
  int num_vertices = 0;       ///< vertices touched by the active edges
  int num_fixed_vertices = 0;
  int num_edges = 0;  ///< active edges (level ≤ the requested level)
  std::string linear_solver;
  std::string report;  ///< Ceres' full report (only with OptimizerOptions::verbose)
};

class PoseGraph {
 public:
  // --- vertices (ids are unique over all vertex types) ---------------------------------------
  bool addVertexSE3(int id, const Eigen::Isometry3d& pose, bool fixed = false);
  bool addVertexSE2(int id, const Pose2& pose, bool fixed = false);
  bool addVertexPointXY(int id, const Eigen::Vector2d& point, bool fixed = false);
  bool addVertexPointXYZ(int id, const Eigen::Vector3d& point, bool fixed = false);
  bool addVertexScale(int id, double scale, bool fixed = false);
  /// Removes the vertex and every edge attached to it; returns false if it did not exist.
  bool removeVertex(int id);

  bool hasVertex(int id) const { return vertices_.count(id) != 0; }
  std::optional<VertexType> vertexType(int id) const;
  /// Estimates; a wrong type or unknown id yields nullopt.
  std::optional<Eigen::Isometry3d> vertexSE3(int id) const;
  std::optional<Pose2> vertexSE2(int id) const;
  std::optional<Eigen::Vector2d> vertexPointXY(int id) const;
  std::optional<Eigen::Vector3d> vertexPointXYZ(int id) const;
  std::optional<double> vertexScale(int id) const;
  bool setVertexSE3(int id, const Eigen::Isometry3d& pose);
  bool setVertexSE2(int id, const Pose2& pose);
  bool setVertexPointXY(int id, const Eigen::Vector2d& point);
  bool setVertexScale(int id, double scale);
  bool setFixed(int id, bool fixed);
  bool isFixed(int id) const;

  // --- edges: each add returns the new edge id, or -1 (see lastError()) ------------------------
  /// measurement = Xfrom⁻¹ · Xto.
  int addEdgeSE3(int from, int to, const Eigen::Isometry3d& measurement,
                 const Matrix6d& information, const EdgeOptions& options = {});
  /// measurement = (R, t) with Xfrom⁻¹ · Xto = (R, s·t), s the scale vertex.
  int addEdgeSE3Scaled(int from, int to, int scale, const Eigen::Isometry3d& measurement,
                       const Matrix6d& information, const EdgeOptions& options = {});
  int addPriorScale(int scale, double measurement, double information,
                    const EdgeOptions& options = {});
  /// e = s_to − s_from − difference.
  int addEdgeScaleDifference(int from, int to, double difference, double information,
                             const EdgeOptions& options = {});
  /// measurement = Xfrom⁻¹ · Xto.
  int addEdgeSE2(int from, int to, const Pose2& measurement, const Eigen::Matrix3d& information,
                 const EdgeOptions& options = {});
  /// measurement = planar(Xrobot)⁻¹ · Xbuilding, planar() = (x, y, yaw) of the SE3 pose. Unlike
  /// g2o's SE2 edge, the translation error is in the estimated building's axes (the information's
  /// frame), so a wall-only constraint leaves the building free along its own wall.
  int addEdgeSE3SE2(int robot, int building, const Pose2& measurement,
                    const Eigen::Matrix3d& information, const EdgeOptions& options = {});
  int addPriorSE3(int vertex, const Eigen::Isometry3d& measurement, const Matrix6d& information,
                  const EdgeOptions& options = {});
  int addPriorSE3XY(int vertex, const Eigen::Vector2d& measurement,
                    const Eigen::Matrix2d& information, const EdgeOptions& options = {});
  int addPriorSE3XYZ(int vertex, const Eigen::Vector3d& measurement,
                     const Eigen::Matrix3d& information, const EdgeOptions& options = {});
  int addPriorSE3Yaw(int vertex, double yaw, double information, const EdgeOptions& options = {});
  int addEdgeSE3YawDifference(int from, int to, double yaw_change, double information,
                              const EdgeOptions& options = {});
  int addPriorSE2(int vertex, const Pose2& measurement, const Eigen::Matrix3d& information,
                  const EdgeOptions& options = {});
  int addPriorPointXYZ(int point, const Eigen::Vector3d& measurement,
                       const Eigen::Matrix3d& information, const EdgeOptions& options = {});
  /// e = Xto − φ·Xfrom (XYZ points), phi = exp(−Δt/τ).
  int addEdgePointXYZGaussMarkov(int from, int to, double phi, const Eigen::Matrix3d& information,
                                 const EdgeOptions& options = {});
  /// e = position(Xpose) + Xoffset − measurement.
  int addEdgeSE3PositionWithOffset(int pose, int offset, const Eigen::Vector3d& measurement,
                                   const Eigen::Matrix3d& information,
                                   const EdgeOptions& options = {});
  /// measurement = Xpose⁻¹ · p (the point in the pose's frame).
  int addEdgeSE2PointXY(int pose, int point, const Eigen::Vector2d& measurement,
                        const Eigen::Matrix2d& information, const EdgeOptions& options = {});
  /// measurement = planar(Xpose)⁻¹ · p.
  int addEdgeSE3PointXY(int pose, int point, const Eigen::Vector2d& measurement,
                        const Eigen::Matrix2d& information, const EdgeOptions& options = {});
  /// e = n·x − c with x = Xline⁻¹ · Xpoint · p: the signed distance of the point p (in the first
  /// vertex's frame) from the line {x : n·x = c} (in the second vertex's frame, unit n). Nothing
  /// is imposed along the line.
  int addEdgeSE2PointOnLine(int point_owner, int line_owner, const Eigen::Vector2d& point,
                            const Eigen::Vector2d& normal, double offset, double information,
                            const EdgeOptions& options = {});
  /// Planes a x + b y + c z + d = 0 ((a, b, c) unit) measured in the frames of two SE3 vertices
  /// that stand on the same plane. e = (n̂ₓ − nₓ, n̂ᵧ − nᵧ, d̂ − d) in the second frame, where
  /// (n̂, d̂) is the first plane carried there: n̂ = R₂ᵀR₁n₁, d̂ = d₁ + (R₁n₁)·(t₂ − t₁).
  int addEdgeSE3PlanePair(int first, int second, const Eigen::Vector4d& plane_in_first,
                          const Eigen::Vector4d& plane_in_second,
                          const Eigen::Matrix3d& information, const EdgeOptions& options = {});
  /// Generic form used by file readers: measurement/information laid out as in EdgeInfo.
  int addEdge(EdgeType type, const std::vector<int>& vertices, const Eigen::VectorXd& measurement,
              const Eigen::MatrixXd& information, const EdgeOptions& options = {});

  bool removeEdge(int edge_id);
  bool setEdgeLevel(int edge_id, int level);
  bool hasEdge(int edge_id) const { return edges_.count(edge_id) != 0; }
  std::optional<EdgeInfo> edge(int edge_id) const;

  // --- queries (ids ascending) --------------------------------------------------------------
  std::vector<int> vertexIds() const;
  std::vector<int> vertexIds(VertexType type) const;
  /// Edges with min_level ≤ level ≤ max_level, optionally of one type.
  std::vector<int> edgeIds(int min_level = 0, int max_level = INT_MAX,
                           std::optional<EdgeType> type = std::nullopt) const;
  std::vector<int> edgesOfVertex(int vertex_id) const;
  /// Vertices touched by at least one edge of level ≤ level (those optimize(level) may move).
  std::vector<int> activeVertexIds(int level) const;
  size_t numVertices() const { return vertices_.size(); }
  size_t numEdges() const { return edges_.size(); }
  int maxLevel() const;  ///< highest edge level (0 for an empty graph)
  const std::string& lastError() const { return last_error_; }

  // --- optimisation ---------------------------------------------------------------------------
  /// Optimises every edge with level ≤ level and only the vertices they touch. Fixed vertices
  /// are never changed (bit for bit). Gauge: fix a vertex or add a prior; otherwise the solution
  /// floats (Levenberg–Marquardt still converges, but covariances are undefined).
  OptimizationResult optimize(int level = INT_MAX, const OptimizerOptions& options = {});
  /// χ² (Σ eᵀΩe, no robust kernel) of every edge with level ≤ level at the current estimates.
  double chi2(int level = INT_MAX) const;
  /// Marginal covariance of one vertex in its tangent space using the edges of level ≤ level:
  /// SE3 6×6 over (δx, δy, δz in the world frame, δθ rotation vector in the body frame),
  /// SE2 3×3 over (x, y, θ), XY 2×2. False (and lastError()) if the vertex is unknown or not
  /// touched, or the problem is rank deficient (unfixed gauge).
  bool marginalCovariance(int vertex_id, Eigen::MatrixXd* covariance, int level = INT_MAX);
  /// The same for several vertices with one factorisation (a fixed vertex's is zero).
  bool marginalCovariances(const std::vector<int>& vertex_ids,
                           std::map<int, Eigen::MatrixXd>* covariances, int level = INT_MAX);

  // --- internal layout, used by src/graph/ (public so the Ceres-side code needs no friends) ----
  struct Vertex {
    VertexType type = VertexType::kSE3;
    bool fixed = false;
    /// SE3: tx, ty, tz, qx, qy, qz, qw (unit); SE2: x, y, θ; XY: x, y; scale: s.
    std::array<double, 7> x{};
  };
  struct Edge {
    EdgeType type = EdgeType::kSE2;
    std::array<int, kMaxEdgeVertices> vertices{{-1, -1, -1}};
    int num_vertices = 0;
    int level = 0;
    RobustKernel kernel;
    Eigen::VectorXd measurement;
    Eigen::MatrixXd information;
    Eigen::MatrixXd sqrt_information;  ///< S with SᵀS = Ω (residual r = S e)
  };
  const std::map<int, Vertex>& vertices() const { return vertices_; }
  const std::map<int, Edge>& edges() const { return edges_; }

 private:
  bool addVertex(int id, VertexType type, const double* x, int n, bool fixed);
  int fail(const std::string& message);

  std::map<int, Vertex> vertices_;  // std::map: stable addresses for Ceres parameter blocks
  std::map<int, Edge> edges_;
  int next_edge_id_ = 0;
  std::string last_error_;
};

}  // namespace osm_graph_slam
