#include "osm_graph_slam/sim/route.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <queue>
#include <set>

#include "osm_graph_slam/common/geometry2d.h"
#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double headingOf(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return std::atan2(b.y() - a.y(), b.x() - a.x());
}

std::vector<double> dijkstra(const RoadGraph& g, int source) {
  std::vector<double> dist(g.nodes.size(), kInf);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  dist[source] = 0.0;
  queue.push({0.0, source});
  while (!queue.empty()) {
    const auto [d, u] = queue.top();
    queue.pop();
    if (d > dist[u]) continue;
    for (int v : g.adjacency[u]) {
      const double nd = d + (g.nodes[u] - g.nodes[v]).norm();
      if (nd < dist[v]) {
        dist[v] = nd;
        queue.push({nd, v});
      }
    }
  }
  return dist;
}

/// Shortest path from cur (entered from prev) to target without U-turns; empty if none.
std::vector<int> pathWithoutUturn(const RoadGraph& g, int prev, int cur, int target) {
  using State = std::pair<int, int>;  // (node, came from)
  std::map<State, double> dist;
  std::map<State, State> parent;
  using Item = std::pair<double, State>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  const State s0{cur, prev};
  dist[s0] = 0.0;
  queue.push({0.0, s0});
  while (!queue.empty()) {
    const auto [d, s] = queue.top();
    queue.pop();
    if (d > dist[s]) continue;
    if (s.first == target && s != s0) {
      std::vector<int> path;
      for (State x = s; x != s0; x = parent[x]) path.push_back(x.first);
      std::reverse(path.begin(), path.end());
      return path;
    }
    for (int v : g.adjacency[s.first]) {
      if (v == s.second) continue;
      const State n{v, s.first};
      const double nd = d + (g.nodes[v] - g.nodes[s.first]).norm();
      auto it = dist.find(n);
      if (it == dist.end() || nd < it->second) {
        dist[n] = nd;
        parent[n] = s;
        queue.push({nd, n});
      }
    }
  }
  return {};
}

}  // namespace

RoadGraph RoadGraph::fromPolylines(const std::vector<Polyline2>& roads) {
  RoadGraph g;
  std::map<std::pair<long long, long long>, int> index;
  auto nodeId = [&](const Eigen::Vector2d& p) {
    const auto key = std::make_pair(std::llround(p.x() * 1000.0), std::llround(p.y() * 1000.0));
    auto it = index.find(key);
    if (it != index.end()) return it->second;
    const int id = int(g.nodes.size());
    index.emplace(key, id);
    g.nodes.push_back(p);
    g.adjacency.emplace_back();
    return id;
  };
  for (const auto& road : roads) {
    for (size_t i = 0; i + 1 < road.size(); ++i) {
      const int a = nodeId(road[i]), b = nodeId(road[i + 1]);
      if (a == b) continue;
      if (std::find(g.adjacency[a].begin(), g.adjacency[a].end(), b) == g.adjacency[a].end()) {
        g.adjacency[a].push_back(b);
        g.adjacency[b].push_back(a);
      }
    }
  }
  return g;
}

size_t RoadGraph::numEdges() const {
  size_t n = 0;
  for (const auto& a : adjacency) n += a.size();
  return n / 2;
}

RoadGraph RoadGraph::drivableCore() const {
  const size_t n = nodes.size();
  std::vector<int> degree(n);
  std::vector<bool> alive(n, true);
  for (size_t i = 0; i < n; ++i) degree[i] = int(adjacency[i].size());
  std::vector<int> stack;
  for (size_t i = 0; i < n; ++i) {
    if (degree[i] < 2) stack.push_back(int(i));
  }
  while (!stack.empty()) {
    const int u = stack.back();
    stack.pop_back();
    if (!alive[u]) continue;
    alive[u] = false;
    for (int v : adjacency[u]) {
      if (alive[v] && --degree[v] < 2) stack.push_back(v);
    }
  }
  // Largest connected component among the survivors.
  std::vector<int> component(n, -1);
  int best = -1;
  size_t best_size = 0;
  for (size_t i = 0, c = 0; i < n; ++i) {
    if (!alive[i] || component[i] >= 0) continue;
    size_t size = 0;
    std::vector<int> queue{int(i)};
    component[i] = int(c);
    while (!queue.empty()) {
      const int u = queue.back();
      queue.pop_back();
      ++size;
      for (int v : adjacency[u]) {
        if (alive[v] && component[v] < 0) {
          component[v] = int(c);
          queue.push_back(v);
        }
      }
    }
    if (size > best_size) {
      best_size = size;
      best = int(c);
    }
    ++c;
  }
  RoadGraph out;
  std::vector<int> remap(n, -1);
  for (size_t i = 0; i < n; ++i) {
    if (alive[i] && component[i] == best) {
      remap[i] = int(out.nodes.size());
      out.nodes.push_back(nodes[i]);
    }
  }
  out.adjacency.resize(out.nodes.size());
  for (size_t i = 0; i < n; ++i) {
    if (remap[i] < 0) continue;
    for (int v : adjacency[i]) {
      if (remap[v] >= 0) out.adjacency[remap[i]].push_back(remap[v]);
    }
  }
  return out;
}

bool planRoute(const RoadGraph& g, const RouteParams& params, Route& route, std::string* error) {
  route = Route();
  if (g.nodes.size() < 3 || g.numEdges() < 3) {
    if (error) *error = "road graph has no loop to drive (fewer than 3 nodes in its 2-core)";
    return false;
  }
  SimRng rng(hashCombine(params.seed, 0x726f757465ULL));
  std::vector<int> junctions;
  for (size_t i = 0; i < g.nodes.size(); ++i) {
    if (g.adjacency[i].size() >= 3) junctions.push_back(int(i));
  }
  const int start = junctions.empty() ? rng.uniformInt(0, int(g.nodes.size()) - 1)
                                      : junctions[rng.uniformInt(0, int(junctions.size()) - 1)];
  const std::vector<double> to_start = dijkstra(g, start);
  std::map<std::pair<int, int>, int> used;
  auto edgeKey = [](int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); };

  route.node_ids = {start};
  int prev = -1, cur = start;
  double length = 0.0;
  for (int step = 0; step < 100000; ++step) {
    std::vector<int> candidates;
    std::vector<double> weights;
    for (int v : g.adjacency[cur]) {
      if (v == prev && g.adjacency[cur].size() > 1) continue;
      double w = 1.0;
      if (prev >= 0) {
        const double turn =
            wrapAngle(headingOf(g.nodes[cur], g.nodes[v]) - headingOf(g.nodes[prev], g.nodes[cur]));
        w = std::exp(-std::abs(turn) / 1.2);
      }
      w *= std::pow(0.2, used[edgeKey(cur, v)]);
      candidates.push_back(v);
      weights.push_back(w);
    }
    double total = 0.0;
    for (double w : weights) total += w;
    double pick = rng.uniform() * total;
    size_t k = 0;
    while (k + 1 < weights.size() && pick >= weights[k]) pick -= weights[k++];
    const int next = candidates[k];
    length += (g.nodes[next] - g.nodes[cur]).norm();
    ++used[edgeKey(cur, next)];
    route.node_ids.push_back(next);
    prev = cur;
    cur = next;
    if (length + to_start[cur] >= params.length) break;
  }
  if (cur != start) {
    std::vector<int> back = pathWithoutUturn(g, prev, cur, start);
    if (back.empty()) {
      if (error) *error = "no way back to the route start without a U-turn";
      return false;
    }
    route.node_ids.insert(route.node_ids.end(), back.begin(), back.end());
  }
  route.length = 0.0;
  for (size_t i = 0; i < route.node_ids.size(); ++i) {
    route.waypoints.push_back(g.nodes[route.node_ids[i]]);
    if (i) route.length += (route.waypoints[i] - route.waypoints[i - 1]).norm();
  }
  return true;
}

Trajectory Trajectory::fromRoute(const Route& route, const RouteParams& params) {
  Trajectory traj;
  Polyline2 w;
  for (const auto& p : route.waypoints) {
    if (w.empty() || (p - w.back()).norm() > 1e-3) w.push_back(p);
  }
  if (w.size() < 2) return traj;
  // Corner fillets: tangent length limited to half of each adjacent segment.
  const size_t n = w.size();
  std::vector<double> tangent(n, 0.0), turn(n, 0.0), radius(n, 0.0);
  for (size_t i = 1; i + 1 < n; ++i) {
    turn[i] = wrapAngle(headingOf(w[i], w[i + 1]) - headingOf(w[i - 1], w[i]));
    const double half = std::min(std::abs(turn[i]), 175.0 * M_PI / 180.0) / 2.0;
    if (half < 1e-4) continue;
    const double limit = 0.5 * std::min((w[i] - w[i - 1]).norm(), (w[i + 1] - w[i]).norm());
    tangent[i] = std::min(params.corner_radius * std::tan(half), limit);
    radius[i] = tangent[i] / std::tan(half);
  }
  // Dense samples of position, heading and curvature every ds.
  const double ds = 0.1;
  std::vector<TrajectoryState> s;
  auto push = [&](const Eigen::Vector2d& p, double yaw, double kappa) {
    TrajectoryState st;
    st.position = p;
    st.yaw = yaw;
    st.curvature = kappa;
    st.s = s.empty() ? 0.0 : s.back().s + (p - s.back().position).norm();
    s.push_back(st);
  };
  double yaw_unwrapped = headingOf(w[0], w[1]);
  Eigen::Vector2d cursor = w[0];
  push(cursor, yaw_unwrapped, 0.0);
  for (size_t i = 1; i < n; ++i) {
    const Eigen::Vector2d dir = (w[i] - w[i - 1]).normalized();
    const Eigen::Vector2d line_end = w[i] - dir * tangent[i];
    const double line_len = (line_end - cursor).norm();
    for (double d = ds; d < line_len; d += ds) push(cursor + dir * d, yaw_unwrapped, 0.0);
    push(line_end, yaw_unwrapped, 0.0);
    cursor = line_end;
    if (i + 1 < n && radius[i] > 0.0) {
      const double kappa = (turn[i] > 0 ? 1.0 : -1.0) / radius[i];
      const double arc = radius[i] * std::abs(turn[i]);
      const double h0 = yaw_unwrapped;
      const Eigen::Vector2d p0 = cursor;
      const int steps = std::max(1, int(std::ceil(arc / ds)));
      for (int k = 1; k <= steps; ++k) {
        const double sigma = arc * k / steps;
        const double h = h0 + kappa * sigma;
        const Eigen::Vector2d p =
            p0 + Eigen::Vector2d(std::sin(h) - std::sin(h0), -std::cos(h) + std::cos(h0)) / kappa;
        push(p, h, kappa);
      }
      yaw_unwrapped = h0 + kappa * arc;
      cursor = s.back().position;
    } else if (i + 1 < n) {
      yaw_unwrapped += turn[i];
    }
  }
  // Speed profile: curvature limit, then forward (acceleration) and backward (braking) passes.
  const size_t m = s.size();
  std::vector<double> v(m);
  for (size_t i = 0; i < m; ++i) {
    const double k = std::abs(s[i].curvature);
    v[i] = k > 1e-9 ? std::min({params.cruise_speed, std::sqrt(params.max_lateral_accel / k),
                                params.max_yaw_rate / k})
                    : params.cruise_speed;
  }
  for (size_t i = 1; i < m; ++i) {
    const double d = s[i].s - s[i - 1].s;
    v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2.0 * params.max_accel * d));
  }
  for (size_t i = m - 1; i-- > 0;) {
    const double d = s[i + 1].s - s[i].s;
    v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2.0 * params.max_decel * d));
  }
  for (size_t i = 0; i < m; ++i) {
    v[i] = std::max(v[i], 0.5);
    s[i].speed = v[i];
    s[i].yaw_rate = v[i] * s[i].curvature;
    if (i > 0) {
      const double d = s[i].s - s[i - 1].s;
      s[i].t = s[i - 1].t + 2.0 * d / (v[i] + v[i - 1]);
      s[i].accel = d > 0 ? (v[i] * v[i] - v[i - 1] * v[i - 1]) / (2.0 * d) : 0.0;
    }
  }
  traj.samples_ = std::move(s);
  return traj;
}

TrajectoryState Trajectory::at(double t) const {
  if (samples_.empty()) return {};
  if (t <= samples_.front().t) return samples_.front();
  if (t >= samples_.back().t) return samples_.back();
  const auto it = std::upper_bound(samples_.begin(), samples_.end(), t,
                                   [](double x, const TrajectoryState& st) { return x < st.t; });
  const TrajectoryState& b = *it;
  const TrajectoryState& a = *(it - 1);
  const double f = (t - a.t) / std::max(b.t - a.t, 1e-12);
  TrajectoryState r;
  r.t = t;
  r.s = a.s + f * (b.s - a.s);
  r.position = a.position + f * (b.position - a.position);
  r.yaw = a.yaw + f * (b.yaw - a.yaw);
  r.speed = a.speed + f * (b.speed - a.speed);
  r.yaw_rate = a.yaw_rate + f * (b.yaw_rate - a.yaw_rate);
  r.accel = b.accel;
  r.curvature = f < 0.5 ? a.curvature : b.curvature;
  return r;
}

double Trajectory::maxYawRate() const {
  double m = 0.0;
  for (const auto& s : samples_) m = std::max(m, std::abs(s.yaw_rate));
  return m;
}

double Trajectory::maxLateralAccel() const {
  double m = 0.0;
  for (const auto& s : samples_) m = std::max(m, s.speed * s.speed * std::abs(s.curvature));
  return m;
}

int countRevisits(const Trajectory& trajectory, double radius, double min_gap, double step) {
  std::vector<Eigen::Vector2d> pts;
  std::vector<double> arc;
  double next = 0.0;
  for (const auto& s : trajectory.samples()) {
    if (s.s >= next) {
      pts.push_back(s.position);
      arc.push_back(s.s);
      next = s.s + step;
    }
  }
  int events = 0;
  bool in_event = false;
  for (size_t i = 0; i < pts.size(); ++i) {
    bool revisit = false;
    for (size_t j = 0; j < i && !revisit; ++j) {
      revisit = arc[i] - arc[j] >= min_gap && (pts[i] - pts[j]).norm() < radius;
    }
    if (revisit && !in_event) ++events;
    in_event = revisit;
  }
  return events;
}

}  // namespace osm_graph_slam::sim
