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

enum class ManoeuvreKind { kSharpTurn, kUTurn, kStop, kDeadEnd };

/// A dead-end street hanging off a node of the drivable core: the polyline from that node to the
/// point where the vehicle turns (short of the street's end by the three-point turn's reach).
struct DeadEndStreet {
  Polyline2 path;       ///< path[0] = the core node
  double length = 0.0;  ///< of the street to its end [m]
  bool valid() const { return path.size() >= 2; }
};

double polylineLength(const Polyline2& p) {
  double l = 0.0;
  for (size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).norm();
  return l;
}

/// For every node of core, the longest dead-end street of full (trees outside the 2-core) that
/// starts there and is dead_end_min_length..max_length long (invalid if none).
std::vector<DeadEndStreet> findDeadEnds(const RoadGraph& core, const RoadGraph& full,
                                        const ManoeuvreParams& mp) {
  std::vector<DeadEndStreet> out(core.nodes.size());
  auto key = [](const Eigen::Vector2d& p) {
    return std::make_pair(std::llround(p.x() * 1000.0), std::llround(p.y() * 1000.0));
  };
  std::map<std::pair<long long, long long>, int> full_index;
  for (size_t i = 0; i < full.nodes.size(); ++i) full_index.emplace(key(full.nodes[i]), int(i));
  std::vector<bool> in_core(full.nodes.size(), false);
  std::vector<int> core_to_full(core.nodes.size(), -1);
  for (size_t i = 0; i < core.nodes.size(); ++i) {
    const auto it = full_index.find(key(core.nodes[i]));
    if (it == full_index.end()) continue;
    core_to_full[i] = it->second;
    in_core[it->second] = true;
  }
  // The turning point stays this far from the street's end (the turn's forward reach + 1 m).
  const double reach = mp.u_turn_radius * std::sin(M_PI / 3.0) + 1.0;
  for (size_t c = 0; c < core.nodes.size(); ++c) {
    const int root = core_to_full[c];
    if (root < 0) continue;
    for (int first : full.adjacency[root]) {
      if (in_core[first]) continue;
      // Depth-first through the tree hanging off root; leaves are the dead ends.
      std::map<int, int> parent{{first, root}};
      std::map<int, double> dist{{first, (full.nodes[first] - full.nodes[root]).norm()}};
      std::vector<int> stack{first};
      while (!stack.empty()) {
        const int u = stack.back();
        stack.pop_back();
        bool leaf = true;
        for (int v : full.adjacency[u]) {
          if (v == parent[u] || in_core[v] || parent.count(v)) continue;
          leaf = false;
          parent[v] = u;
          dist[v] = dist[u] + (full.nodes[v] - full.nodes[u]).norm();
          stack.push_back(v);
        }
        const double d = dist[u];
        if (!leaf || d < mp.dead_end_min_length || d > mp.dead_end_max_length) continue;
        if (out[c].valid() && d <= out[c].length) continue;
        Polyline2 path;
        for (int x = u; x != root; x = parent[x]) path.push_back(full.nodes[x]);
        path.push_back(full.nodes[root]);
        std::reverse(path.begin(), path.end());
        // Cut the path at length - reach.
        const double cut = d - reach;
        if (cut < 1.0) continue;
        Polyline2 cut_path{path[0]};
        double l = 0.0;
        for (size_t i = 1; i < path.size(); ++i) {
          const double seg = (path[i] - path[i - 1]).norm();
          if (l + seg >= cut) {
            cut_path.push_back(path[i - 1] + (path[i] - path[i - 1]) * ((cut - l) / seg));
            break;
          }
          l += seg;
          cut_path.push_back(path[i]);
        }
        out[c].path = cut_path;
        out[c].length = d;
      }
    }
  }
  return out;
}

/// The longest straight run of core edges (every vertex turning at most max_turn and the whole
/// run within 2 max_turn of its first heading), at most long_straight_max_length (unless its
/// first edge is longer).
std::vector<int> longestStraight(const RoadGraph& g, const ManoeuvreParams& mp) {
  const double max_turn = mp.long_straight_max_turn_deg * M_PI / 180.0;
  std::vector<int> best;
  double best_length = 0.0;
  for (size_t a = 0; a < g.nodes.size(); ++a) {
    for (int b : g.adjacency[a]) {
      std::vector<int> chain{int(a), b};
      double length = (g.nodes[b] - g.nodes[a]).norm();
      const double h0 = headingOf(g.nodes[a], g.nodes[b]);
      while (length < mp.long_straight_max_length) {
        const int u = chain[chain.size() - 2], v = chain.back();
        const double h = headingOf(g.nodes[u], g.nodes[v]);
        int next = -1;
        double next_turn = max_turn;
        for (int c : g.adjacency[v]) {
          if (c == u || std::find(chain.begin(), chain.end(), c) != chain.end()) continue;
          const double hc = headingOf(g.nodes[v], g.nodes[c]);
          const double turn = std::abs(wrapAngle(hc - h));
          if (turn <= next_turn && std::abs(wrapAngle(hc - h0)) <= 2.0 * max_turn) {
            next = c;
            next_turn = turn;
          }
        }
        if (next < 0) break;
        const double edge = (g.nodes[next] - g.nodes[v]).norm();
        if (length + edge > mp.long_straight_max_length) break;
        length += edge;
        chain.push_back(next);
      }
      if (length > best_length + 1e-9) {
        best_length = length;
        best = chain;
      }
    }
  }
  return best;
}

}  // namespace

bool parseManoeuvreList(const std::string& list, ManoeuvreParams& params, std::string* error) {
  ManoeuvreParams p = params;
  p.sharp_turn = p.u_turn = p.stop = p.dead_end = p.long_straight = false;
  size_t pos = 0;
  while (pos <= list.size()) {
    const size_t comma = std::min(list.find(',', pos), list.size());
    const std::string name = list.substr(pos, comma - pos);
    pos = comma + 1;
    if (name == "none" || name.empty()) continue;
    if (name == "all") {
      p.sharp_turn = p.u_turn = p.stop = p.dead_end = p.long_straight = true;
    } else if (name == "sharp_turn") {
      p.sharp_turn = true;
    } else if (name == "u_turn") {
      p.u_turn = true;
    } else if (name == "stop") {
      p.stop = true;
    } else if (name == "dead_end") {
      p.dead_end = true;
    } else if (name == "long_straight") {
      p.long_straight = true;
    } else {
      if (error) {
        *error = "unknown manoeuvre '" + name +
                 "' (none, all, sharp_turn, u_turn, stop, dead_end, long_straight)";
      }
      return false;
    }
  }
  params = p;
  return true;
}

std::string manoeuvreList(const ManoeuvreParams& p) {
  std::string out;
  auto add = [&](bool on, const char* name) {
    if (!on) return;
    if (!out.empty()) out += ',';
    out += name;
  };
  add(p.sharp_turn, "sharp_turn");
  add(p.u_turn, "u_turn");
  add(p.stop, "stop");
  add(p.dead_end, "dead_end");
  add(p.long_straight, "long_straight");
  return out.empty() ? "none" : out;
}

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

bool planRoute(const RoadGraph& g, const RouteParams& params, Route& route, std::string* error,
               const RoadGraph* full_graph) {
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
  int start = junctions.empty() ? rng.uniformInt(0, int(g.nodes.size()) - 1)
                                : junctions[rng.uniformInt(0, int(junctions.size()) - 1)];
  if (params.start_near) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < g.nodes.size(); ++i) {
      const bool candidate = junctions.empty() || g.adjacency[i].size() >= 3;
      const double d = (g.nodes[i] - *params.start_near).norm();
      if (candidate && d < best) best = d, start = int(i);
    }
  }
  const ManoeuvreParams& mp = params.manoeuvres;
  const bool with_manoeuvres = mp.any();
  const std::vector<int> straight =
      with_manoeuvres && mp.long_straight ? longestStraight(g, mp) : std::vector<int>();
  if (straight.size() >= 2) start = straight.front();
  const std::vector<double> to_start = dijkstra(g, start);
  std::map<std::pair<int, int>, int> used;
  auto edgeKey = [](int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); };

  // id: node of g or -1 (a point that is not one of its nodes).
  auto append = [&](int id, const Eigen::Vector2d& p) {
    route.node_ids.push_back(id);
    route.waypoints.push_back(p);
    if (with_manoeuvres) route.actions.push_back(WaypointAction::kNone);
  };
  append(start, g.nodes[start]);
  int prev = -1, cur = start;
  double length = 0.0;
  // Moves to the neighbour `next` of cur.
  auto stepTo = [&](int next) {
    length += (g.nodes[next] - g.nodes[cur]).norm();
    ++used[edgeKey(cur, next)];
    append(next, g.nodes[next]);
    prev = cur;
    cur = next;
  };

  // Manoeuvres: their own random stream, so that the walk without them stays as it was.
  SimRng mrng(hashCombine(params.seed, 0x6d616e6f65757672ULL));
  std::vector<ManoeuvreKind> pending;
  std::vector<DeadEndStreet> dead_ends;
  bool any_dead_end = false;
  if (with_manoeuvres) {
    if (straight.size() >= 2) {
      ManoeuvreEvent ev;
      ev.type = "long_straight";
      for (size_t k = 1; k < straight.size(); ++k) stepTo(straight[k]);
      ev.last_waypoint = route.waypoints.size() - 1;
      ev.length = length;
      route.manoeuvres.push_back(ev);
    }
    auto add = [&](bool on, int count, ManoeuvreKind kind) {
      for (int i = 0; on && i < count; ++i) pending.push_back(kind);
    };
    add(mp.sharp_turn, mp.sharp_turns, ManoeuvreKind::kSharpTurn);
    add(mp.u_turn, mp.u_turns, ManoeuvreKind::kUTurn);
    add(mp.stop, mp.stops, ManoeuvreKind::kStop);
    add(mp.dead_end, mp.dead_ends, ManoeuvreKind::kDeadEnd);
    for (size_t i = pending.size(); i > 1; --i) {
      std::swap(pending[i - 1], pending[size_t(mrng.uniformInt(0, int(i) - 1))]);
    }
    if (mp.dead_end && full_graph) {
      dead_ends = findDeadEnds(g, *full_graph, mp);
      for (const auto& d : dead_ends) any_dead_end = any_dead_end || d.valid();
    }
  }
  const double spacing = std::max(mp.spacing, 0.7 * params.length / double(pending.size() + 1));
  double next_trigger = length + spacing;
  constexpr double kGiveUp = 1000.0;  // [m] of walking without a place for the manoeuvre
  // Incoming heading at the last waypoint.
  auto incoming = [&]() {
    const size_t k = route.waypoints.size();
    return std::make_pair(headingOf(route.waypoints[k - 2], route.waypoints[k - 1]),
                          (route.waypoints[k - 1] - route.waypoints[k - 2]).norm());
  };
  // A three-point turn in the middle of the street cur -> one of its neighbours; false if no
  // street is long enough.
  auto midStreetUturn = [&](const std::string& type, bool fallback) {
    std::vector<int> candidates;
    for (int v : g.adjacency[cur]) {
      if (v != prev && (g.nodes[v] - g.nodes[cur]).norm() >= mp.u_turn_min_street)
        candidates.push_back(v);
    }
    if (candidates.empty()) return false;
    const int v = candidates[size_t(mrng.uniformInt(0, int(candidates.size()) - 1))];
    const Eigen::Vector2d mid = 0.5 * (g.nodes[cur] + g.nodes[v]);
    ManoeuvreEvent ev;
    ev.type = type;
    ev.fallback = fallback;
    const size_t before = route.waypoints.size() - 1;
    append(-1, mid);
    route.actions.back() = WaypointAction::kUTurn;
    const size_t turn_point = route.waypoints.size() - 1;
    append(cur, g.nodes[cur]);
    // A U-turn is the turn itself; a dead end (here its fallback) the way in and out.
    ev.first_waypoint = fallback ? before : turn_point;
    ev.last_waypoint = fallback ? route.waypoints.size() - 1 : turn_point;
    ev.length = (mid - g.nodes[cur]).norm();
    length += 2.0 * ev.length;
    ++used[edgeKey(cur, v)];
    prev = v;  // back at cur as if arriving from v
    route.manoeuvres.push_back(ev);
    return true;
  };
  // Tries the manoeuvre at cur: not possible here, done at cur (a stop: the walk goes on from
  // cur), or done and the walk moved on.
  enum class Outcome { kNotHere, kDoneHere, kMoved };
  auto tryManoeuvre = [&](ManoeuvreKind kind) -> Outcome {
    const auto moved = [](bool ok) { return ok ? Outcome::kMoved : Outcome::kNotHere; };
    switch (kind) {
      case ManoeuvreKind::kSharpTurn: {
        const auto [heading, in_length] = incoming();
        if (in_length < 4.0) return Outcome::kNotHere;
        std::vector<int> candidates;
        for (int v : g.adjacency[cur]) {
          if (v == prev || (g.nodes[v] - g.nodes[cur]).norm() < 4.0) continue;
          const double turn =
              std::abs(wrapAngle(headingOf(g.nodes[cur], g.nodes[v]) - heading)) * 180.0 / M_PI;
          if (turn >= mp.sharp_turn_min_deg && turn <= mp.sharp_turn_max_deg)
            candidates.push_back(v);
        }
        if (candidates.empty()) return Outcome::kNotHere;
        ManoeuvreEvent ev;
        ev.type = "sharp_turn";
        ev.first_waypoint = ev.last_waypoint = route.waypoints.size() - 1;
        route.actions.back() = WaypointAction::kSharpTurn;
        route.manoeuvres.push_back(ev);
        stepTo(candidates[size_t(mrng.uniformInt(0, int(candidates.size()) - 1))]);
        return Outcome::kMoved;
      }
      case ManoeuvreKind::kStop: {
        if (incoming().second < 20.0) return Outcome::kNotHere;
        ManoeuvreEvent ev;
        ev.type = "stop";
        ev.first_waypoint = ev.last_waypoint = route.waypoints.size() - 1;
        route.actions.back() = WaypointAction::kStop;
        route.manoeuvres.push_back(ev);
        return Outcome::kDoneHere;
      }
      case ManoeuvreKind::kUTurn:
        return moved(midStreetUturn("u_turn", false));
      case ManoeuvreKind::kDeadEnd: {
        if (!any_dead_end) return moved(midStreetUturn("dead_end", true));
        if (!dead_ends[cur].valid()) {
          // Drive to the nearest node with a dead-end street (or fall back to a U-turn).
          const std::vector<double> dist = dijkstra(g, cur);
          int target = -1;
          for (size_t i = 0; i < g.nodes.size(); ++i) {
            if (dead_ends[i].valid() && dist[i] <= mp.dead_end_max_detour &&
                (target < 0 || dist[i] < dist[target]))
              target = int(i);
          }
          const std::vector<int> path =
              target < 0 ? std::vector<int>() : pathWithoutUturn(g, prev, cur, target);
          if (path.empty()) return moved(midStreetUturn("dead_end", true));
          for (int v : path) stepTo(v);
        }
        const DeadEndStreet& street = dead_ends[cur];
        ManoeuvreEvent ev;
        ev.type = "dead_end";
        ev.first_waypoint = route.waypoints.size() - 1;
        ev.length = street.length;
        for (size_t k = 1; k < street.path.size(); ++k) append(-1, street.path[k]);
        route.actions.back() = WaypointAction::kUTurn;
        for (size_t k = street.path.size() - 1; k-- > 1;) append(-1, street.path[k]);
        append(cur, g.nodes[cur]);
        ev.last_waypoint = route.waypoints.size() - 1;
        length += 2.0 * polylineLength(street.path);
        prev = -1;  // back from outside the core: every street of cur is a way on
        route.manoeuvres.push_back(ev);
        return Outcome::kMoved;
      }
    }
    return Outcome::kNotHere;
  };

  for (int step = 0; step < 100000; ++step) {
    if (!pending.empty() && length >= next_trigger) {
      const Outcome outcome = tryManoeuvre(pending.front());
      if (outcome != Outcome::kNotHere || length >= next_trigger + kGiveUp) {
        if (outcome == Outcome::kNotHere) ++route.manoeuvres_skipped;
        pending.erase(pending.begin());
        next_trigger = length + spacing;
      }
      if (outcome == Outcome::kMoved) {
        if (length + to_start[cur] >= params.length && pending.empty()) break;
        continue;
      }
    }
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
    stepTo(candidates[k]);
    if (length + to_start[cur] >= params.length && pending.empty()) break;
  }
  if (cur != start) {
    std::vector<int> back = pathWithoutUturn(g, prev, cur, start);
    if (back.empty()) {
      if (error) *error = "no way back to the route start without a U-turn";
      return false;
    }
    for (int v : back) append(v, g.nodes[v]);
  }
  route.length = 0.0;
  for (size_t i = 1; i < route.waypoints.size(); ++i) {
    route.length += (route.waypoints[i] - route.waypoints[i - 1]).norm();
  }
  return true;
}

Trajectory Trajectory::fromRoute(const Route& route, const RouteParams& params) {
  Trajectory traj;
  const ManoeuvreParams& mp = params.manoeuvres;
  const bool has_actions = route.actions.size() == route.waypoints.size();
  Polyline2 w;
  std::vector<WaypointAction> action;
  std::vector<size_t> dedup_index(route.waypoints.size(), 0);  // route waypoint -> w
  for (size_t j = 0; j < route.waypoints.size(); ++j) {
    const Eigen::Vector2d& p = route.waypoints[j];
    const WaypointAction a = has_actions ? route.actions[j] : WaypointAction::kNone;
    if (w.empty() || (p - w.back()).norm() > 1e-3) {
      w.push_back(p);
      action.push_back(a);
    } else if (a != WaypointAction::kNone) {
      action.back() = a;
    }
    dedup_index[j] = w.size() - 1;
  }
  if (w.size() < 2) return traj;
  // Corner fillets: tangent length limited to half of each adjacent segment. No fillet where the
  // vehicle turns around (a three-point turn instead).
  const size_t n = w.size();
  std::vector<double> tangent(n, 0.0), turn(n, 0.0), radius(n, 0.0);
  for (size_t i = 1; i + 1 < n; ++i) {
    turn[i] = wrapAngle(headingOf(w[i], w[i + 1]) - headingOf(w[i - 1], w[i]));
    if (action[i] == WaypointAction::kUTurn) continue;
    const double half = std::min(std::abs(turn[i]), 175.0 * M_PI / 180.0) / 2.0;
    if (half < 1e-4) continue;
    const double limit = 0.5 * std::min((w[i] - w[i - 1]).norm(), (w[i + 1] - w[i]).norm());
    const double corner_radius =
        action[i] == WaypointAction::kSharpTurn ? mp.sharp_turn_radius : params.corner_radius;
    tangent[i] = std::min(corner_radius * std::tan(half), limit);
    radius[i] = tangent[i] / std::tan(half);
  }
  // Per-sample limits of the speed profile (for the segment that ends at the sample).
  struct Limits {
    double cruise, lateral, yaw_rate, accel, decel;
    double direction = 1.0;  ///< +1 forward, -1 reverse
    bool stop = false;       ///< speed 0 here
    double dwell = 0.0;      ///< standstill before this sample [s] (same position as the last)
  };
  const Limits normal{params.cruise_speed, params.max_lateral_accel, params.max_yaw_rate,
                      params.max_accel, params.max_decel};
  Limits limits = normal;
  std::vector<Limits> lim;
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
    lim.push_back(limits);
  };
  // Standing still at the last sample for `dwell` seconds.
  auto standstill = [&](double dwell) {
    lim.back().stop = true;
    if (dwell <= 0.0) return;
    const TrajectoryState last = s.back();
    push(last.position, last.yaw, 0.0);
    lim.back().stop = true;
    lim.back().dwell = dwell;
  };
  // An arc of `angle` [rad] turning at heading rate k per metre, driven in `direction`.
  auto turnArc = [&](double& yaw, double k, double angle, double direction) {
    const double length = angle / std::abs(k);
    const double h0 = yaw;
    const Eigen::Vector2d p0 = s.back().position;
    const int steps = std::max(1, int(std::ceil(length / ds)));
    limits.direction = direction;
    for (int j = 1; j <= steps; ++j) {
      const double h = h0 + k * length * j / steps;
      const Eigen::Vector2d p =
          p0 +
          direction * Eigen::Vector2d(std::sin(h) - std::sin(h0), -std::cos(h) + std::cos(h0)) / k;
      push(p, h, direction * k);
    }
    limits.direction = 1.0;
    yaw = h0 + k * length;
  };
  // Per vertex of w: samples where it begins (the fillet's start), where its stop or three-point
  // turn ends and where it ends (after the fillet).
  std::vector<size_t> begin_sample(n, 0), action_end_sample(n, 0), end_sample(n, 0);
  double yaw_unwrapped = headingOf(w[0], w[1]);
  Eigen::Vector2d cursor = w[0];
  push(cursor, yaw_unwrapped, 0.0);
  for (size_t i = 1; i < n; ++i) {
    const Eigen::Vector2d dir = (w[i] - w[i - 1]).normalized();
    const Eigen::Vector2d line_end = w[i] - dir * tangent[i];
    const double line_len = (line_end - cursor).norm();
    for (double d = ds; d < line_len; d += ds) push(cursor + dir * d, yaw_unwrapped, 0.0);
    push(line_end, yaw_unwrapped, 0.0);
    limits = normal;  // a sharp turn's strong acceleration lasts until the next vertex
    begin_sample[i] = s.size() - 1;
    cursor = line_end;
    if (i + 1 < n && action[i] == WaypointAction::kStop) standstill(mp.stop_duration);
    action_end_sample[i] = s.size() - 1;
    if (i + 1 < n && action[i] == WaypointAction::kUTurn) {
      // Three-point turn to the left: forward left, reverse right, forward left (60 deg each):
      // back on the line at w[i], heading reversed, within +-radius/2 of it.
      const double k = 1.0 / mp.u_turn_radius;
      standstill(mp.u_turn_pause);
      limits.cruise = mp.u_turn_speed;
      turnArc(yaw_unwrapped, k, M_PI / 3.0, 1.0);
      standstill(mp.u_turn_pause);
      turnArc(yaw_unwrapped, k, M_PI / 3.0, -1.0);
      standstill(mp.u_turn_pause);
      turnArc(yaw_unwrapped, k, M_PI / 3.0, 1.0);
      standstill(0.0);
      limits = normal;
      cursor = s.back().position;
      action_end_sample[i] = s.size() - 1;
    } else if (i + 1 < n && radius[i] > 0.0) {
      const bool sharp = action[i] == WaypointAction::kSharpTurn;
      if (sharp) {
        limits.cruise = std::min(params.cruise_speed, mp.sharp_turn_speed);
        limits.lateral = mp.sharp_turn_max_lateral_accel;
        limits.yaw_rate = mp.sharp_turn_max_yaw_rate;
      }
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
      if (sharp) {
        limits = normal;
        limits.accel = mp.sharp_turn_accel;
      }
    } else if (i + 1 < n) {
      yaw_unwrapped += turn[i];
    }
    end_sample[i] = s.size() - 1;
  }
  // Speed profile: curvature limit, then forward (acceleration) and backward (braking) passes;
  // then, if the vehicle stops anywhere, the stops and the same passes again.
  const size_t m = s.size();
  std::vector<double> v(m);
  for (size_t i = 0; i < m; ++i) {
    const double k = std::abs(s[i].curvature);
    v[i] = k > 1e-9 ? std::min({lim[i].cruise, std::sqrt(lim[i].lateral / k), lim[i].yaw_rate / k})
                    : lim[i].cruise;
  }
  auto passes = [&]() {
    for (size_t i = 1; i < m; ++i) {
      const double d = s[i].s - s[i - 1].s;
      v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2.0 * lim[i].accel * d));
    }
    for (size_t i = m - 1; i-- > 0;) {
      const double d = s[i + 1].s - s[i].s;
      v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2.0 * lim[i + 1].decel * d));
    }
  };
  passes();
  bool stops = false;
  for (const Limits& l : lim) stops = stops || l.stop;
  for (size_t i = 0; i < m; ++i) v[i] = std::max(v[i], 0.5);
  if (stops) {
    for (size_t i = 0; i < m; ++i) {
      if (lim[i].stop) v[i] = 0.0;
    }
    passes();
  }
  for (size_t i = 0; i < m; ++i) {
    s[i].speed = lim[i].direction * v[i];
    s[i].yaw_rate = s[i].speed * s[i].curvature;
    if (i > 0) {
      const double d = s[i].s - s[i - 1].s;
      if (lim[i].dwell > 0.0) {
        s[i].t = s[i - 1].t + lim[i].dwell;
      } else {
        s[i].t = s[i - 1].t + (v[i] + v[i - 1] > 0.0 ? 2.0 * d / (v[i] + v[i - 1]) : 0.0);
      }
      s[i].accel = d > 0 ? lim[i].direction * (v[i] * v[i] - v[i - 1] * v[i - 1]) / (2.0 * d) : 0.0;
    }
  }
  begin_sample[0] = end_sample[0] = 0;
  traj.samples_ = std::move(s);
  for (ManoeuvreEvent ev : route.manoeuvres) {
    if (ev.first_waypoint >= dedup_index.size() || ev.last_waypoint >= dedup_index.size()) continue;
    const TrajectoryState& a = traj.samples_[begin_sample[dedup_index[ev.first_waypoint]]];
    const size_t last = dedup_index[ev.last_waypoint];
    const bool at_vertex = ev.type == "stop" || ev.type == "u_turn";
    const TrajectoryState& b =
        traj.samples_[at_vertex ? action_end_sample[last] : end_sample[last]];
    ev.t_begin = a.t;
    ev.s_begin = a.s;
    ev.t_end = b.t;
    ev.s_end = b.s;
    traj.manoeuvres_.push_back(ev);
  }
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

namespace {

/// Largest longitudinal acceleration between samples where |speed| grows (speeding_up) or falls.
double maxLongitudinal(const std::vector<TrajectoryState>& samples, bool speeding_up) {
  double m = 0.0;
  for (size_t i = 1; i < samples.size(); ++i) {
    const double dv = std::abs(samples[i].speed) - std::abs(samples[i - 1].speed);
    if (speeding_up ? dv > 0.0 : dv < 0.0) m = std::max(m, std::abs(samples[i].accel));
  }
  return m;
}

}  // namespace

double Trajectory::maxAccel() const {
  return maxLongitudinal(samples_, true);
}

double Trajectory::maxDecel() const {
  return maxLongitudinal(samples_, false);
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
