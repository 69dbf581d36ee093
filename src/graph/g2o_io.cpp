#include "osm_graph_slam/graph/g2o_io.h"

#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include "osm_graph_slam/common/upper_triangle.h"

namespace osm_graph_slam {
namespace {

struct VertexRecord {
  int line = 0;
  int id = 0;
  VertexType type = VertexType::kSE2;
  Eigen::VectorXd values;
};

struct EdgeRecord {
  int line = 0;
  EdgeType type = EdgeType::kSE2;
  std::vector<int> ids;
  Eigen::VectorXd measurement;
  Eigen::MatrixXd information;
};

struct FixRecord {
  int line = 0;
  int id = 0;
};

struct ParsedFile {
  std::vector<VertexRecord> vertices;
  std::vector<EdgeRecord> edges;
  std::vector<FixRecord> fixes;
};

G2oReadResult failAt(int line, const std::string& message) {
  G2oReadResult r;
  r.ok = false;
  r.line = line;
  r.message = (line > 0 ? "line " + std::to_string(line) + ": " : std::string()) + message;
  return r;
}

bool parseInt(const std::string& token, int* value) {
  errno = 0;
  char* end = nullptr;
  const long v = std::strtol(token.c_str(), &end, 10);
  if (errno != 0 || end == token.c_str() || *end != '\0') return false;
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) return false;
  *value = static_cast<int>(v);
  return true;
}

bool parseDouble(const std::string& token, double* value) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(token.c_str(), &end);
  if (errno == ERANGE || end == token.c_str() || *end != '\0' || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

// Layout of one tag: number of integer ids, measurement size, information size.
struct TagLayout {
  bool is_vertex = false;
  VertexType vertex_type = VertexType::kSE2;
  EdgeType edge_type = EdgeType::kSE2;
  int num_ids = 1;
  int num_values = 0;  ///< vertex estimate or edge measurement
  int info_dim = 0;
};

bool tagLayout(const std::string& tag, TagLayout* layout) {
  if (tag == "VERTEX_SE2") {
    *layout = {true, VertexType::kSE2, EdgeType::kSE2, 1, 3, 0};
  } else if (tag == "VERTEX_SE3:QUAT") {
    *layout = {true, VertexType::kSE3, EdgeType::kSE3, 1, 7, 0};
  } else if (tag == "VERTEX_XY") {
    *layout = {true, VertexType::kPointXY, EdgeType::kSE2, 1, 2, 0};
  } else if (tag == "VERTEX_TRACKXYZ") {
    *layout = {true, VertexType::kPointXYZ, EdgeType::kSE2, 1, 3, 0};
  } else if (tag == "EDGE_SE2") {
    *layout = {false, VertexType::kSE2, EdgeType::kSE2, 2, 3, 3};
  } else if (tag == "EDGE_SE3:QUAT") {
    *layout = {false, VertexType::kSE3, EdgeType::kSE3, 2, 7, 6};
  } else if (tag == "EDGE_SE2_XY") {
    *layout = {false, VertexType::kSE2, EdgeType::kSE2PointXY, 2, 2, 2};
  } else if (tag == "EDGE_PRIOR_SE2") {
    *layout = {false, VertexType::kSE2, EdgeType::kPriorSE2, 1, 3, 3};
  } else {
    return false;
  }
  return true;
}

// Parses one non-empty line into the file records; returns an error message or "".
std::string parseLine(const std::vector<std::string>& tokens, int line, ParsedFile* file) {
  const std::string& tag = tokens[0];
  if (tag == "FIX") {
    if (tokens.size() < 2) return "FIX needs at least one vertex id";
    for (size_t k = 1; k < tokens.size(); ++k) {
      FixRecord fix{line, 0};
      if (!parseInt(tokens[k], &fix.id)) return "FIX: '" + tokens[k] + "' is not a vertex id";
      file->fixes.push_back(fix);
    }
    return "";
  }
  TagLayout layout;
  if (!tagLayout(tag, &layout)) return "unknown tag '" + tag + "'";
  const int num_info = layout.info_dim * (layout.info_dim + 1) / 2;
  const size_t expected = 1 + layout.num_ids + layout.num_values + num_info;
  if (tokens.size() != expected) {
    return tag + " expects " + std::to_string(expected - 1) + " values, got " +
           std::to_string(tokens.size() - 1);
  }
  std::vector<int> ids(layout.num_ids);
  for (int k = 0; k < layout.num_ids; ++k) {
    if (!parseInt(tokens[1 + k], &ids[k])) {
      return tag + ": '" + tokens[1 + k] + "' is not a vertex id";
    }
  }
  std::vector<double> values(layout.num_values + num_info);
  for (size_t k = 0; k < values.size(); ++k) {
    const std::string& token = tokens[1 + layout.num_ids + k];
    if (!parseDouble(token, &values[k])) return tag + ": '" + token + "' is not a finite number";
  }
  const Eigen::VectorXd measurement =
      Eigen::Map<const Eigen::VectorXd>(values.data(), layout.num_values);
  if (layout.num_values == 7 && measurement.tail<4>().norm() < 1e-9) {
    return tag + ": quaternion has zero norm";
  }
  if (layout.is_vertex) {
    file->vertices.push_back({line, ids[0], layout.vertex_type, measurement});
  } else {
    file->edges.push_back({line, layout.edge_type, ids, measurement,
                           upperTriangleToMatrix(values, layout.num_values, layout.info_dim)});
  }
  return "";
}

// Vertex types implied by an edge's endpoints.
std::vector<VertexType> endpointTypes(EdgeType type) {
  switch (type) {
    case EdgeType::kSE3:
      return {VertexType::kSE3, VertexType::kSE3};
    case EdgeType::kSE2PointXY:
      return {VertexType::kSE2, VertexType::kPointXY};
    case EdgeType::kPriorSE2:
      return {VertexType::kSE2};
    default:
      return {VertexType::kSE2, VertexType::kSE2};
  }
}

Eigen::Isometry3d isometryFromVector(const Eigen::VectorXd& v) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::Quaterniond(v[6], v[3], v[4], v[5]).normalized().toRotationMatrix();
  t.translation() = v.head<3>();
  return t;
}

Eigen::VectorXd vectorFromIsometry(const Eigen::Isometry3d& t) {
  Eigen::VectorXd v(7);
  const Eigen::Quaterniond q(t.linear());
  v << t.translation(), q.x(), q.y(), q.z(), q.w();
  return v;
}

Pose2 pose2FromVector(const Eigen::VectorXd& v) {
  return {v[0], v[1], v[2]};
}

Eigen::VectorXd vectorFromPose2(const Pose2& p) {
  return Eigen::Vector3d(p.x, p.y, p.theta);
}

// Pose of `to` (or `from` when inverse) from the other end and a relative-pose measurement.
Eigen::VectorXd composePose(VertexType type, const Eigen::VectorXd& known,
                            const Eigen::VectorXd& measurement, bool inverse) {
  if (type == VertexType::kSE3) {
    const Eigen::Isometry3d z = isometryFromVector(measurement);
    const Eigen::Isometry3d x = isometryFromVector(known);
    return vectorFromIsometry(inverse ? x * z.inverse() : x * z);
  }
  const Pose2 z = pose2FromVector(measurement);
  const Pose2 x = pose2FromVector(known);
  return vectorFromPose2(inverse ? x * z.inverse() : x * z);
}

Eigen::VectorXd identityOf(VertexType type) {
  if (type == VertexType::kSE3) {
    Eigen::VectorXd v = Eigen::VectorXd::Zero(7);
    v[6] = 1.0;
    return v;
  }
  return Eigen::VectorXd::Zero(type == VertexType::kSE2 || type == VertexType::kPointXYZ ? 3 : 2);
}

// Estimates for vertices that only appear in edges: the odometry chain first, then any edge.
class MissingVertexInitialiser {
 public:
  MissingVertexInitialiser(const ParsedFile& file, std::map<int, Eigen::VectorXd>* estimates,
                           const std::map<int, VertexType>& types)
      : file_(file), estimates_(*estimates), types_(types) {}

  // Returns the id of a vertex that could not be reached, or nullopt.
  std::optional<int> run(const std::set<int>& missing) {
    if (missing.empty()) return std::nullopt;
    if (estimates_.empty()) {
      const int first = *missing.begin();
      estimates_[first] = identityOf(types_.at(first));
      ++initialised_;
    }
    followOdometryChain(missing);
    breadthFirst();
    for (int id : missing) {
      if (!estimates_.count(id)) return id;
    }
    return std::nullopt;
  }
  int initialised() const { return initialised_; }

 private:
  bool isPoseEdge(const EdgeRecord& e) const {
    return e.type == EdgeType::kSE2 || e.type == EdgeType::kSE3;
  }

  // Initialises the unknown end of a pose edge from the known end; true if it did.
  bool initialiseFrom(const EdgeRecord& e) {
    const bool from_known = estimates_.count(e.ids[0]) != 0;
    const bool to_known = estimates_.count(e.ids[1]) != 0;
    if (from_known == to_known) return false;
    const int known = from_known ? e.ids[0] : e.ids[1];
    const int unknown = from_known ? e.ids[1] : e.ids[0];
    estimates_[unknown] =
        composePose(types_.at(unknown), estimates_.at(known), e.measurement, !from_known);
    ++initialised_;
    return true;
  }

  void followOdometryChain(const std::set<int>& missing) {
    std::map<std::pair<int, int>, const EdgeRecord*> consecutive;
    for (const EdgeRecord& e : file_.edges) {
      if (!isPoseEdge(e) || std::abs(static_cast<long>(e.ids[0]) - e.ids[1]) != 1) continue;
      consecutive.emplace(std::minmax(e.ids[0], e.ids[1]), &e);
    }
    bool progress = true;
    while (progress) {
      progress = false;
      // (ids at the ends of the int range have no neighbour there: id ± 1 would overflow)
      for (int id : missing) {  // forward: id from id − 1
        if (estimates_.count(id) || id == std::numeric_limits<int>::min()) continue;
        const auto it = consecutive.find({id - 1, id});
        if (it != consecutive.end() && initialiseFrom(*it->second)) progress = true;
      }
      for (auto rit = missing.rbegin(); rit != missing.rend(); ++rit) {  // backward
        if (estimates_.count(*rit) || *rit == std::numeric_limits<int>::max()) continue;
        const auto it = consecutive.find({*rit, *rit + 1});
        if (it != consecutive.end() && initialiseFrom(*it->second)) progress = true;
      }
    }
  }

  void breadthFirst() {
    std::map<int, std::vector<const EdgeRecord*>> adjacency;
    for (const EdgeRecord& e : file_.edges) {
      if (e.ids.size() != 2) continue;
      adjacency[e.ids[0]].push_back(&e);
      adjacency[e.ids[1]].push_back(&e);
    }
    std::deque<int> queue;
    for (const auto& [id, x] : estimates_) queue.push_back(id);
    while (!queue.empty()) {
      const int v = queue.front();
      queue.pop_front();
      for (const EdgeRecord* e : adjacency[v]) {
        const int other = e->ids[0] == v ? e->ids[1] : e->ids[0];
        if (estimates_.count(other)) continue;
        if (isPoseEdge(*e)) {
          initialiseFrom(*e);
        } else if (e->type == EdgeType::kSE2PointXY && other == e->ids[1]) {
          estimates_[other] = pose2FromVector(estimates_.at(v)).transform(e->measurement);
          ++initialised_;
        } else {
          continue;
        }
        queue.push_back(other);
      }
    }
  }

  const ParsedFile& file_;
  std::map<int, Eigen::VectorXd>& estimates_;
  const std::map<int, VertexType>& types_;
  int initialised_ = 0;
};

G2oReadResult buildGraph(const ParsedFile& file, const G2oReadOptions& options, PoseGraph* out) {
  std::map<int, VertexType> types;
  std::map<int, Eigen::VectorXd> estimates;
  for (const VertexRecord& v : file.vertices) {
    if (!types.emplace(v.id, v.type).second) {
      return failAt(v.line, "vertex " + std::to_string(v.id) + " is declared twice");
    }
    estimates[v.id] = v.values;
  }
  std::set<int> missing;
  for (const EdgeRecord& e : file.edges) {
    const std::vector<VertexType> expected = endpointTypes(e.type);
    for (size_t k = 0; k < e.ids.size(); ++k) {
      const auto [it, inserted] = types.emplace(e.ids[k], expected[k]);
      if (inserted) missing.insert(e.ids[k]);
      if (it->second != expected[k]) {
        return failAt(e.line, "vertex " + std::to_string(e.ids[k]) + " is " + toString(it->second) +
                                  " but the edge needs " + toString(expected[k]));
      }
    }
  }
  MissingVertexInitialiser initialiser(file, &estimates, types);
  if (const std::optional<int> lost = initialiser.run(missing)) {
    for (const EdgeRecord& e : file.edges) {
      for (int id : e.ids) {
        if (id == *lost) {
          return failAt(e.line, "vertex " + std::to_string(id) +
                                    " is not declared and not connected to any vertex with a "
                                    "known pose");
        }
      }
    }
  }

  PoseGraph graph;
  for (const auto& [id, type] : types) {
    const Eigen::VectorXd& x = estimates.at(id);
    bool ok = false;
    if (type == VertexType::kSE3) ok = graph.addVertexSE3(id, isometryFromVector(x));
    if (type == VertexType::kSE2) ok = graph.addVertexSE2(id, pose2FromVector(x));
    if (type == VertexType::kPointXY) ok = graph.addVertexPointXY(id, x.head<2>());
    if (type == VertexType::kPointXYZ) ok = graph.addVertexPointXYZ(id, x.head<3>());
    if (!ok) {
      int line = 0;
      for (const VertexRecord& v : file.vertices) line = v.id == id ? v.line : line;
      return failAt(line, graph.lastError());
    }
  }
  G2oReadResult result;
  for (const EdgeRecord& e : file.edges) {
    Eigen::MatrixXd repaired;
    double min_eigenvalue = 0.0;
    const bool indefinite = nearestPositiveSemiDefinite(e.information, &repaired, &min_eigenvalue);
    if (indefinite && options.repair_information) {
      result.repairs.push_back({e.line, min_eigenvalue, (repaired - e.information).norm()});
    }
    const Eigen::MatrixXd& information =
        indefinite && options.repair_information ? repaired : e.information;
    if (graph.addEdge(e.type, e.ids, e.measurement, information) < 0) {
      std::string message = graph.lastError();
      if (indefinite) {
        std::ostringstream hint;
        hint << " (smallest eigenvalue " << min_eigenvalue
             << "; reading with repair_information, e.g. graph_benchmark --repair-information, "
                "projects it to the nearest positive semi-definite matrix)";
        message += hint.str();
      }
      return failAt(e.line, message);
    }
  }
  result.num_repaired_information = static_cast<int>(result.repairs.size());
  for (const FixRecord& f : file.fixes) {
    if (!graph.setFixed(f.id, true)) {
      return failAt(f.line, "FIX: unknown vertex " + std::to_string(f.id));
    }
    ++result.num_fixed;
  }
  result.ok = true;
  result.num_vertices = static_cast<int>(graph.numVertices());
  result.num_edges = static_cast<int>(graph.numEdges());
  result.num_initialised = initialiser.initialised();
  *out = std::move(graph);
  return result;
}

void writeValues(std::ostream& out, const Eigen::VectorXd& v) {
  for (int k = 0; k < v.size(); ++k) out << ' ' << v[k];
}

}  // namespace

bool nearestPositiveSemiDefinite(const Eigen::MatrixXd& information, Eigen::MatrixXd* repaired,
                                 double* min_eigenvalue) {
  if (information.size() == 0 || information.rows() != information.cols() ||
      !information.allFinite()) {
    return false;
  }
  const Eigen::MatrixXd symmetric = 0.5 * (information + information.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(symmetric);
  if (eig.info() != Eigen::Success) return false;
  const double smallest = eig.eigenvalues().minCoeff();
  if (min_eigenvalue) *min_eigenvalue = smallest;
  // The tolerance of PoseGraph::addEdge: below it the edge would be refused.
  const double scale = std::max(1.0, information.cwiseAbs().maxCoeff());
  if (smallest >= -1e-9 * scale) return false;
  const Eigen::VectorXd clamped = eig.eigenvalues().cwiseMax(0.0);
  const Eigen::MatrixXd projected =
      eig.eigenvectors() * clamped.asDiagonal() * eig.eigenvectors().transpose();
  *repaired = 0.5 * (projected + projected.transpose());  // exactly symmetric
  return true;
}

G2oReadResult readG2o(std::istream& in, PoseGraph* graph, const G2oReadOptions& options) {
  ParsedFile file;
  std::string text;
  int line = 0;
  while (std::getline(in, text)) {
    ++line;
    const size_t hash = text.find('#');
    if (hash != std::string::npos) text.resize(hash);
    std::istringstream tokens_in(text);
    std::vector<std::string> tokens;
    for (std::string t; tokens_in >> t;) tokens.push_back(t);
    if (tokens.empty()) continue;
    const std::string error = parseLine(tokens, line, &file);
    if (!error.empty()) return failAt(line, error);
  }
  if (in.bad()) return failAt(line, "read error");
  if (file.vertices.empty() && file.edges.empty()) return failAt(0, "no vertex and no edge");
  return buildGraph(file, options, graph);
}

G2oReadResult readG2o(const std::string& path, PoseGraph* graph, const G2oReadOptions& options) {
  std::ifstream in(path);
  if (!in) return failAt(0, "cannot open '" + path + "'");
  G2oReadResult r = readG2o(in, graph, options);
  if (!r.ok) r.message = path + ": " + r.message;
  return r;
}

G2oWriteResult writeG2o(const PoseGraph& graph, std::ostream& out) {
  G2oWriteResult result;
  out << std::setprecision(std::numeric_limits<double>::max_digits10);
  for (const auto& [id, v] : graph.vertices()) {
    switch (v.type) {
      case VertexType::kSE3:
        out << "VERTEX_SE3:QUAT " << id;
        writeValues(out, Eigen::Map<const Eigen::VectorXd>(v.x.data(), 7));
        break;
      case VertexType::kSE2:
        out << "VERTEX_SE2 " << id;
        writeValues(out, Eigen::Map<const Eigen::VectorXd>(v.x.data(), 3));
        break;
      case VertexType::kPointXY:
        out << "VERTEX_XY " << id;
        writeValues(out, Eigen::Map<const Eigen::VectorXd>(v.x.data(), 2));
        break;
      case VertexType::kPointXYZ:
        out << "VERTEX_TRACKXYZ " << id;
        writeValues(out, Eigen::Map<const Eigen::VectorXd>(v.x.data(), 3));
        break;
      case VertexType::kScale:
        ++result.num_skipped_vertices;
        continue;
    }
    out << '\n';
    ++result.num_vertices;
  }
  for (const auto& [id, v] : graph.vertices()) {
    if (v.fixed && v.type != VertexType::kScale) out << "FIX " << id << '\n';
  }
  for (const auto& [id, e] : graph.edges()) {
    const char* tag = nullptr;
    if (e.type == EdgeType::kSE2) tag = "EDGE_SE2";
    if (e.type == EdgeType::kSE3Scaled) tag = "EDGE_SE3:QUAT";
    if (e.type == EdgeType::kSE3) tag = "EDGE_SE3:QUAT";
    if (e.type == EdgeType::kSE2PointXY) tag = "EDGE_SE2_XY";
    if (e.type == EdgeType::kPriorSE2) tag = "EDGE_PRIOR_SE2";
    if (tag == nullptr) {
      ++result.num_skipped_edges;
      continue;
    }
    Eigen::VectorXd measurement = e.measurement;
    int num_ids = e.num_vertices;
    if (e.type == EdgeType::kSE3Scaled) {  // g2o has no scale: the edge at today's estimate
      measurement.head<2>() *= graph.vertexScale(e.vertices[2]).value_or(1.0);
      num_ids = 2;
    }
    out << tag;
    for (int k = 0; k < num_ids; ++k) out << ' ' << e.vertices[k];
    writeValues(out, measurement);
    writeUpperTriangle(out, e.information);
    out << '\n';
    ++result.num_edges;
  }
  result.ok = static_cast<bool>(out);
  if (!result.ok) result.message = "write error";
  return result;
}

G2oWriteResult writeG2o(const PoseGraph& graph, const std::string& path) {
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  G2oWriteResult result;
  {
    std::ofstream out(tmp);
    if (!out) {
      result.message = "cannot write '" + tmp + "'";
      return result;
    }
    result = writeG2o(graph, out);
    out.close();
    if (result.ok && !out) {
      result.ok = false;
      result.message = "write error on '" + tmp + "'";
    }
  }
  if (result.ok && std::rename(tmp.c_str(), path.c_str()) != 0) {
    result.ok = false;
    result.message = "cannot rename '" + tmp + "' to '" + path + "'";
  }
  if (!result.ok) std::remove(tmp.c_str());
  return result;
}

}  // namespace osm_graph_slam
