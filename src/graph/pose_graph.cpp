// Pose graph storage, validation and queries (no Ceres here; see pose_graph_optimizer.cpp).
#include "osm_graph_slam/graph/pose_graph.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <sstream>

namespace osm_graph_slam {
namespace {

struct EdgeSignature {
  int num_vertices;
  std::array<VertexType, kMaxEdgeVertices> types;  ///< the first num_vertices are used
};

EdgeSignature signatureOf(EdgeType type) {
  using V = VertexType;
  switch (type) {
    case EdgeType::kSE3:
      return {2, {V::kSE3, V::kSE3}};
    case EdgeType::kSE2:
      return {2, {V::kSE2, V::kSE2}};
    case EdgeType::kSE3SE2:
      return {2, {V::kSE3, V::kSE2}};
    case EdgeType::kPriorSE3:
    case EdgeType::kPriorSE3XY:
    case EdgeType::kPriorSE3XYZ:
    case EdgeType::kPriorSE3Yaw:
      return {1, {V::kSE3}};
    case EdgeType::kPriorSE2:
      return {1, {V::kSE2}};
    case EdgeType::kSE2PointXY:
      return {2, {V::kSE2, V::kPointXY}};
    case EdgeType::kSE3PointXY:
      return {2, {V::kSE3, V::kPointXY}};
    case EdgeType::kSE2PointOnLine:
      return {2, {V::kSE2, V::kSE2}};
    case EdgeType::kSE3PlanePair:
      return {2, {V::kSE3, V::kSE3}};
    case EdgeType::kPriorPointXYZ:
      return {1, {V::kPointXYZ}};
    case EdgeType::kPointXYZGaussMarkov:
      return {2, {V::kPointXYZ, V::kPointXYZ}};
    case EdgeType::kSE3PositionWithOffset:
      return {2, {V::kSE3, V::kPointXYZ}};
    case EdgeType::kSE3YawDifference:
      return {2, {V::kSE3, V::kSE3}};
    case EdgeType::kSE3Scaled:
      return {3, {V::kSE3, V::kSE3, V::kScale}};
    case EdgeType::kPriorScale:
      return {1, {V::kScale}};
    case EdgeType::kScaleDifference:
      return {2, {V::kScale, V::kScale}};
  }
  return {0, {V::kSE3}};
}

bool allFinite(const Eigen::MatrixXd& m) {
  return m.array().isFinite().all();
}

// S with SᵀS = Ω; false if Ω is not symmetric positive semi-definite.
bool sqrtInformation(const Eigen::MatrixXd& info, Eigen::MatrixXd* sqrt_info, std::string* why) {
  const double scale = std::max(1.0, info.cwiseAbs().maxCoeff());
  if ((info - info.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    *why = "information matrix is not symmetric";
    return false;
  }
  Eigen::LLT<Eigen::MatrixXd> llt(info);
  if (llt.info() == Eigen::Success) {
    *sqrt_info = llt.matrixU();
    return true;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(info);
  if (eig.info() != Eigen::Success || eig.eigenvalues().minCoeff() < -1e-9 * scale) {
    *why = "information matrix is not positive semi-definite";
    return false;
  }
  const Eigen::VectorXd root = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  *sqrt_info = root.asDiagonal() * eig.eigenvectors().transpose();
  return true;
}

Eigen::VectorXd se3Vector(const Eigen::Isometry3d& pose) {
  Eigen::VectorXd v(7);
  const Eigen::Quaterniond q(pose.linear());
  v << pose.translation(), q.x(), q.y(), q.z(), q.w();
  return v;
}

Eigen::VectorXd se2Vector(const Pose2& p) {
  Eigen::VectorXd v(3);
  v << p.x, p.y, p.theta;
  return v;
}

}  // namespace

const char* toString(VertexType type) {
  switch (type) {
    case VertexType::kSE3:
      return "SE3";
    case VertexType::kSE2:
      return "SE2";
    case VertexType::kPointXY:
      return "XY";
    case VertexType::kPointXYZ:
      return "XYZ";
    case VertexType::kScale:
      return "scale";
  }
  return "?";
}

const char* toString(EdgeType type) {
  switch (type) {
    case EdgeType::kSE3:
      return "SE3";
    case EdgeType::kSE2:
      return "SE2";
    case EdgeType::kSE3SE2:
      return "SE3-SE2";
    case EdgeType::kPriorSE3:
      return "prior SE3";
    case EdgeType::kPriorSE3XY:
      return "prior SE3 xy";
    case EdgeType::kPriorSE3XYZ:
      return "prior SE3 xyz";
    case EdgeType::kPriorSE3Yaw:
      return "prior SE3 yaw";
    case EdgeType::kPriorSE2:
      return "prior SE2";
    case EdgeType::kSE2PointXY:
      return "SE2-XY";
    case EdgeType::kSE3PointXY:
      return "SE3-XY";
    case EdgeType::kSE2PointOnLine:
      return "SE2 point-on-line";
    case EdgeType::kSE3PlanePair:
      return "SE3 plane pair";
    case EdgeType::kPriorPointXYZ:
      return "prior XYZ";
    case EdgeType::kPointXYZGaussMarkov:
      return "XYZ Gauss-Markov";
    case EdgeType::kSE3PositionWithOffset:
      return "SE3 position + XYZ offset";
    case EdgeType::kSE3YawDifference:
      return "SE3 yaw difference";
    case EdgeType::kSE3Scaled:
      return "SE3 scaled";
    case EdgeType::kPriorScale:
      return "prior scale";
    case EdgeType::kScaleDifference:
      return "scale difference";
  }
  return "?";
}

const char* toString(TerminationReason reason) {
  switch (reason) {
    case TerminationReason::kConverged:
      return "converged";
    case TerminationReason::kMaxIterations:
      return "max_iterations";
    case TerminationReason::kNothingToSolve:
      return "nothing_to_solve";
    case TerminationReason::kFailure:
      return "failure";
  }
  return "?";
}

int errorDimension(EdgeType type) {
  switch (type) {
    case EdgeType::kSE3:
    case EdgeType::kSE3Scaled:
    case EdgeType::kPriorSE3:
      return 6;
    case EdgeType::kSE2:
    case EdgeType::kSE3SE2:
    case EdgeType::kPriorSE2:
    case EdgeType::kPriorSE3XYZ:
    case EdgeType::kSE3PlanePair:
    case EdgeType::kPriorPointXYZ:
    case EdgeType::kPointXYZGaussMarkov:
    case EdgeType::kSE3PositionWithOffset:
      return 3;
    case EdgeType::kPriorSE3XY:
    case EdgeType::kSE2PointXY:
    case EdgeType::kSE3PointXY:
      return 2;
    case EdgeType::kSE3YawDifference:
    case EdgeType::kPriorSE3Yaw:
    case EdgeType::kSE2PointOnLine:
    case EdgeType::kPriorScale:
    case EdgeType::kScaleDifference:
      return 1;
  }
  return 0;
}

int measurementDimension(EdgeType type) {
  if (type == EdgeType::kSE3 || type == EdgeType::kSE3Scaled || type == EdgeType::kPriorSE3)
    return 7;
  if (type == EdgeType::kSE2PointOnLine) return 5;
  if (type == EdgeType::kSE3PlanePair) return 8;
  if (type == EdgeType::kPointXYZGaussMarkov) return 1;
  return errorDimension(type);
}

// ---- vertices -----------------------------------------------------------------------------------

int PoseGraph::fail(const std::string& message) {
  last_error_ = message;
  return -1;
}

bool PoseGraph::addVertex(int id, VertexType type, const double* x, int n, bool fixed) {
  if (vertices_.count(id)) {
    fail("vertex " + std::to_string(id) + " already exists");
    return false;
  }
  for (int k = 0; k < n; ++k) {
    if (!std::isfinite(x[k])) {
      fail("vertex " + std::to_string(id) + " has a non-finite estimate");
      return false;
    }
  }
  Vertex v;
  v.type = type;
  v.fixed = fixed;
  std::copy(x, x + n, v.x.begin());
  vertices_.emplace(id, v);
  return true;
}

bool PoseGraph::addVertexSE3(int id, const Eigen::Isometry3d& pose, bool fixed) {
  const Eigen::VectorXd v = se3Vector(pose);
  if (!addVertex(id, VertexType::kSE3, v.data(), 7, fixed)) return false;
  return setVertexSE3(id, pose);  // normalises the quaternion
}

bool PoseGraph::addVertexSE2(int id, const Pose2& pose, bool fixed) {
  const double x[3] = {pose.x, pose.y, wrapAngle(pose.theta)};
  return addVertex(id, VertexType::kSE2, x, 3, fixed);
}

bool PoseGraph::addVertexPointXY(int id, const Eigen::Vector2d& point, bool fixed) {
  return addVertex(id, VertexType::kPointXY, point.data(), 2, fixed);
}

bool PoseGraph::addVertexPointXYZ(int id, const Eigen::Vector3d& point, bool fixed) {
  return addVertex(id, VertexType::kPointXYZ, point.data(), 3, fixed);
}

bool PoseGraph::addVertexScale(int id, double scale, bool fixed) {
  return addVertex(id, VertexType::kScale, &scale, 1, fixed);
}

bool PoseGraph::removeVertex(int id) {
  if (!vertices_.count(id)) return false;
  for (int e : edgesOfVertex(id)) edges_.erase(e);
  vertices_.erase(id);
  return true;
}

std::optional<VertexType> PoseGraph::vertexType(int id) const {
  const auto it = vertices_.find(id);
  if (it == vertices_.end()) return std::nullopt;
  return it->second.type;
}

std::optional<Eigen::Isometry3d> PoseGraph::vertexSE3(int id) const {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kSE3) return std::nullopt;
  const auto& x = it->second.x;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Quaterniond(x[6], x[3], x[4], x[5]).toRotationMatrix();
  pose.translation() << x[0], x[1], x[2];
  return pose;
}

std::optional<Pose2> PoseGraph::vertexSE2(int id) const {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kSE2) return std::nullopt;
  const auto& x = it->second.x;
  return Pose2(x[0], x[1], x[2]);
}

std::optional<Eigen::Vector2d> PoseGraph::vertexPointXY(int id) const {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kPointXY) return std::nullopt;
  return Eigen::Vector2d(it->second.x[0], it->second.x[1]);
}

std::optional<Eigen::Vector3d> PoseGraph::vertexPointXYZ(int id) const {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kPointXYZ) return std::nullopt;
  return Eigen::Vector3d(it->second.x[0], it->second.x[1], it->second.x[2]);
}

std::optional<double> PoseGraph::vertexScale(int id) const {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kScale) return std::nullopt;
  return it->second.x[0];
}

bool PoseGraph::setVertexSE3(int id, const Eigen::Isometry3d& pose) {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kSE3) return false;
  const Eigen::VectorXd v = se3Vector(pose);
  if (!allFinite(v)) return false;
  Eigen::Map<Eigen::Vector4d> q(it->second.x.data() + 3);
  std::copy(v.data(), v.data() + 7, it->second.x.begin());
  q.normalize();
  return true;
}

bool PoseGraph::setVertexSE2(int id, const Pose2& pose) {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kSE2) return false;
  if (!std::isfinite(pose.x) || !std::isfinite(pose.y) || !std::isfinite(pose.theta)) return false;
  it->second.x[0] = pose.x;
  it->second.x[1] = pose.y;
  it->second.x[2] = wrapAngle(pose.theta);
  return true;
}

bool PoseGraph::setVertexPointXY(int id, const Eigen::Vector2d& point) {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kPointXY) return false;
  if (!allFinite(point)) return false;
  it->second.x[0] = point.x();
  it->second.x[1] = point.y();
  return true;
}

bool PoseGraph::setVertexScale(int id, double scale) {
  const auto it = vertices_.find(id);
  if (it == vertices_.end() || it->second.type != VertexType::kScale || !std::isfinite(scale))
    return false;
  it->second.x[0] = scale;
  return true;
}

bool PoseGraph::setFixed(int id, bool fixed) {
  const auto it = vertices_.find(id);
  if (it == vertices_.end()) return false;
  it->second.fixed = fixed;
  return true;
}

bool PoseGraph::isFixed(int id) const {
  const auto it = vertices_.find(id);
  return it != vertices_.end() && it->second.fixed;
}

// ---- edges
// ----------------------------------------------------------------------------------------

int PoseGraph::addEdge(EdgeType type, const std::vector<int>& ids,
                       const Eigen::VectorXd& measurement, const Eigen::MatrixXd& information,
                       const EdgeOptions& options) {
  const EdgeSignature sig = signatureOf(type);
  const std::string what = std::string("edge ") + toString(type);
  if (static_cast<int>(ids.size()) != sig.num_vertices) {
    return fail(what + " needs " + std::to_string(sig.num_vertices) + " vertices");
  }
  for (size_t k = 0; k < ids.size(); ++k) {
    const auto it = vertices_.find(ids[k]);
    if (it == vertices_.end()) return fail(what + ": unknown vertex " + std::to_string(ids[k]));
    const VertexType expected = sig.types[k];
    if (it->second.type != expected) {
      return fail(what + ": vertex " + std::to_string(ids[k]) + " is " + toString(it->second.type) +
                  ", expected " + toString(expected));
    }
  }
  for (size_t k = 1; k < ids.size(); ++k)
    if (std::find(ids.begin(), ids.begin() + k, ids[k]) != ids.begin() + k)
      return fail(what + " connects a vertex to itself");
  if (options.level < 0) return fail(what + ": optimisation level must be >= 0");
  if (options.kernel.type != RobustKernelType::kNone &&
      !(options.kernel.width > 0.0 && std::isfinite(options.kernel.width))) {
    return fail(what + ": robust kernel width must be positive");
  }
  const int dim = errorDimension(type);
  if (measurement.size() != measurementDimension(type) || !allFinite(measurement)) {
    return fail(what + ": measurement must have " + std::to_string(measurementDimension(type)) +
                " finite values");
  }
  if (information.rows() != dim || information.cols() != dim || !allFinite(information)) {
    return fail(what + ": information must be a finite " + std::to_string(dim) + "x" +
                std::to_string(dim) + " matrix");
  }
  Edge edge;
  edge.type = type;
  edge.num_vertices = sig.num_vertices;
  for (size_t k = 0; k < ids.size(); ++k) edge.vertices[k] = ids[k];
  edge.level = options.level;
  edge.kernel = options.kernel;
  edge.measurement = measurement;
  edge.information = information;
  std::string why;
  if (!sqrtInformation(information, &edge.sqrt_information, &why)) return fail(what + ": " + why);
  if (measurementDimension(type) == 7) {
    const double norm = measurement.tail<4>().norm();
    if (norm < 1e-9) return fail(what + ": measurement quaternion is zero");
    edge.measurement.tail<4>() /= norm;
  }
  const int id = next_edge_id_++;
  edges_.emplace(id, std::move(edge));
  return id;
}

int PoseGraph::addEdgeSE3(int from, int to, const Eigen::Isometry3d& measurement,
                          const Matrix6d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kSE3, {from, to}, se3Vector(measurement), information, options);
}

int PoseGraph::addEdgeSE3Scaled(int from, int to, int scale, const Eigen::Isometry3d& measurement,
                                const Matrix6d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kSE3Scaled, {from, to, scale}, se3Vector(measurement), information,
                 options);
}

int PoseGraph::addPriorScale(int scale, double measurement, double information,
                             const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorScale, {scale}, Eigen::VectorXd::Constant(1, measurement),
                 Eigen::MatrixXd::Constant(1, 1, information), options);
}

int PoseGraph::addEdgeScaleDifference(int from, int to, double difference, double information,
                                      const EdgeOptions& options) {
  return addEdge(EdgeType::kScaleDifference, {from, to}, Eigen::VectorXd::Constant(1, difference),
                 Eigen::MatrixXd::Constant(1, 1, information), options);
}

int PoseGraph::addEdgeSE2(int from, int to, const Pose2& measurement,
                          const Eigen::Matrix3d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kSE2, {from, to}, se2Vector(measurement), information, options);
}

int PoseGraph::addEdgeSE3SE2(int robot, int building, const Pose2& measurement,
                             const Eigen::Matrix3d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kSE3SE2, {robot, building}, se2Vector(measurement), information,
                 options);
}

int PoseGraph::addPriorSE3(int vertex, const Eigen::Isometry3d& measurement,
                           const Matrix6d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorSE3, {vertex}, se3Vector(measurement), information, options);
}

int PoseGraph::addPriorSE3XY(int vertex, const Eigen::Vector2d& measurement,
                             const Eigen::Matrix2d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorSE3XY, {vertex}, measurement, information, options);
}

int PoseGraph::addPriorSE3XYZ(int vertex, const Eigen::Vector3d& measurement,
                              const Eigen::Matrix3d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorSE3XYZ, {vertex}, measurement, information, options);
}

int PoseGraph::addPriorSE3Yaw(int vertex, double yaw, double information,
                              const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorSE3Yaw, {vertex}, Eigen::VectorXd::Constant(1, yaw),
                 Eigen::MatrixXd::Constant(1, 1, information), options);
}

int PoseGraph::addEdgeSE3YawDifference(int from, int to, double yaw_change, double information,
                                       const EdgeOptions& options) {
  return addEdge(EdgeType::kSE3YawDifference, {from, to}, Eigen::VectorXd::Constant(1, yaw_change),
                 Eigen::MatrixXd::Constant(1, 1, information), options);
}

int PoseGraph::addPriorSE2(int vertex, const Pose2& measurement, const Eigen::Matrix3d& information,
                           const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorSE2, {vertex}, se2Vector(measurement), information, options);
}

int PoseGraph::addEdgeSE2PointOnLine(int point_owner, int line_owner, const Eigen::Vector2d& point,
                                     const Eigen::Vector2d& normal, double offset,
                                     double information, const EdgeOptions& options) {
  const double norm = normal.norm();
  if (!(norm > 1e-9) || !std::isfinite(norm)) return fail("edge SE2 point-on-line: zero normal");
  Eigen::VectorXd m(5);
  m << point, normal / norm, offset / norm;
  return addEdge(EdgeType::kSE2PointOnLine, {point_owner, line_owner}, m,
                 Eigen::Matrix<double, 1, 1>(information), options);
}

int PoseGraph::addEdgeSE3PlanePair(int first, int second, const Eigen::Vector4d& plane_in_first,
                                   const Eigen::Vector4d& plane_in_second,
                                   const Eigen::Matrix3d& information, const EdgeOptions& options) {
  const double n1 = plane_in_first.head<3>().norm(), n2 = plane_in_second.head<3>().norm();
  if (!(n1 > 1e-9) || !(n2 > 1e-9) || !std::isfinite(n1) || !std::isfinite(n2))
    return fail("edge SE3 plane pair: zero normal");
  Eigen::VectorXd m(8);
  m << plane_in_first / n1, plane_in_second / n2;
  return addEdge(EdgeType::kSE3PlanePair, {first, second}, m, information, options);
}

int PoseGraph::addEdgeSE2PointXY(int pose, int point, const Eigen::Vector2d& measurement,
                                 const Eigen::Matrix2d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kSE2PointXY, {pose, point}, measurement, information, options);
}

int PoseGraph::addEdgeSE3PointXY(int pose, int point, const Eigen::Vector2d& measurement,
                                 const Eigen::Matrix2d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kSE3PointXY, {pose, point}, measurement, information, options);
}

int PoseGraph::addPriorPointXYZ(int point, const Eigen::Vector3d& measurement,
                                const Eigen::Matrix3d& information, const EdgeOptions& options) {
  return addEdge(EdgeType::kPriorPointXYZ, {point}, measurement, information, options);
}

int PoseGraph::addEdgePointXYZGaussMarkov(int from, int to, double phi,
                                          const Eigen::Matrix3d& information,
                                          const EdgeOptions& options) {
  return addEdge(EdgeType::kPointXYZGaussMarkov, {from, to}, Eigen::VectorXd::Constant(1, phi),
                 information, options);
}

int PoseGraph::addEdgeSE3PositionWithOffset(int pose, int offset,
                                            const Eigen::Vector3d& measurement,
                                            const Eigen::Matrix3d& information,
                                            const EdgeOptions& options) {
  return addEdge(EdgeType::kSE3PositionWithOffset, {pose, offset}, measurement, information,
                 options);
}

bool PoseGraph::removeEdge(int edge_id) {
  return edges_.erase(edge_id) != 0;
}

bool PoseGraph::setEdgeLevel(int edge_id, int level) {
  const auto it = edges_.find(edge_id);
  if (it == edges_.end() || level < 0) return false;
  it->second.level = level;
  return true;
}

std::optional<EdgeInfo> PoseGraph::edge(int edge_id) const {
  const auto it = edges_.find(edge_id);
  if (it == edges_.end()) return std::nullopt;
  const Edge& e = it->second;
  EdgeInfo info;
  info.id = edge_id;
  info.type = e.type;
  info.vertices.assign(e.vertices.begin(), e.vertices.begin() + e.num_vertices);
  info.level = e.level;
  info.kernel = e.kernel;
  info.measurement = e.measurement;
  info.information = e.information;
  return info;
}

// ---- queries
// --------------------------------------------------------------------------------------

std::vector<int> PoseGraph::vertexIds() const {
  std::vector<int> ids;
  ids.reserve(vertices_.size());
  for (const auto& [id, v] : vertices_) ids.push_back(id);
  return ids;
}

std::vector<int> PoseGraph::vertexIds(VertexType type) const {
  std::vector<int> ids;
  for (const auto& [id, v] : vertices_) {
    if (v.type == type) ids.push_back(id);
  }
  return ids;
}

std::vector<int> PoseGraph::edgeIds(int min_level, int max_level,
                                    std::optional<EdgeType> type) const {
  std::vector<int> ids;
  for (const auto& [id, e] : edges_) {
    if (e.level < min_level || e.level > max_level) continue;
    if (type && e.type != *type) continue;
    ids.push_back(id);
  }
  return ids;
}

std::vector<int> PoseGraph::edgesOfVertex(int vertex_id) const {
  std::vector<int> ids;
  for (const auto& [id, e] : edges_) {
    if (std::find(e.vertices.begin(), e.vertices.begin() + e.num_vertices, vertex_id) !=
        e.vertices.begin() + e.num_vertices)
      ids.push_back(id);
  }
  return ids;
}

std::vector<int> PoseGraph::activeVertexIds(int level) const {
  std::set<int> ids;
  for (const auto& [id, e] : edges_) {
    if (e.level > level) continue;
    for (int k = 0; k < e.num_vertices; ++k) ids.insert(e.vertices[k]);
  }
  return {ids.begin(), ids.end()};
}

int PoseGraph::maxLevel() const {
  int level = 0;
  for (const auto& [id, e] : edges_) level = std::max(level, e.level);
  return level;
}

}  // namespace osm_graph_slam
