#include "osm_graph_slam/sim/gnss_canyon.h"

#include <algorithm>
#include <cmath>

#include "osm_graph_slam/common/polygon2d.h"
#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr uint64_t kRangeNoiseTag = 0x7072616e6765ULL;  // "prange"
constexpr uint64_t kClockTag = 0x636c6f636bULL;         // "clock"

bool hasHeight(const SimBuilding& b) {
  return std::isfinite(b.height) && b.height > 0.0 && std::isfinite(b.top_z) &&
         std::isfinite(b.base_z) && b.top_z > b.base_z;
}

/// Nearest-rank percentile of unsorted values (0 for none).
double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t rank = size_t(std::ceil(fraction * double(values.size())));
  return values[std::clamp<size_t>(rank, 1, values.size()) - 1];
}

}  // namespace

std::string CanyonGnss::worldProblem(const World& world) {
  if (world.buildings.empty())
    return "the canyon GNSS model needs buildings with heights, and this world has no building "
           "(it would be a silent open sky; use --gnss-model noisy)";
  size_t missing = 0;
  const SimBuilding* first = nullptr;
  for (const SimBuilding& b : world.buildings) {
    if (hasHeight(b)) continue;
    if (!first) first = &b;
    ++missing;
  }
  if (missing == 0) return "";
  return "the canyon GNSS model needs building heights, and " + std::to_string(missing) + " of " +
         std::to_string(world.buildings.size()) + " buildings have none (first: id " +
         std::to_string(first->osm_id) + ")";
}

CanyonGnss::CanyonGnss(const World& world, const CanyonGnssParams& params, uint64_t seed)
    : CanyonGnss(world, params, seed, Constellation::draw(params.constellation, seed)) {}

CanyonGnss::CanyonGnss(const World& world, const CanyonGnssParams& params, uint64_t seed,
                       Constellation constellation)
    : params_(params),
      seed_(seed),
      constellation_(std::move(constellation)),
      prisms_(world.buildings) {
  SimRng clock(hashCombine(seed, kClockTag));
  clock_bias_m_ = clock.uniform(-params.clock_bias_max_m, params.clock_bias_max_m);
  clock_drift_m_s_ = clock.uniform(-params.clock_drift_max_m_s, params.clock_drift_max_m_s);
}

std::vector<int> CanyonGnss::facadesAround(const Eigen::Vector3d& antenna) const {
  // A facade blocks a satellite above the mask only within (roof - antenna) / tan(mask)
  // horizontally; a reflection's second leg starts up to max_reflector_distance away.
  const double tan_mask = std::tan(std::max(params_.constellation.elevation_mask_deg, 1.0) * kDeg);
  auto reach = [&](double top_z) {
    return std::max(0.0, top_z - antenna.z()) / tan_mask + params_.max_reflector_distance;
  };
  std::vector<int> near = prisms_.facadesNear(antenna.head<2>(), reach(prisms_.maxTopZ()));
  const auto& facades = prisms_.facades();
  near.erase(std::remove_if(near.begin(), near.end(),
                            [&](int i) {
                              const Facade& f = facades[size_t(i)];
                              return pointSegmentDistance(antenna.head<2>(),
                                                          LineSegment2(f.a, f.b)) > reach(f.top_z);
                            }),
             near.end());
  return near;
}

SatelliteSignal CanyonGnss::signal(size_t i, double t, const Eigen::Vector3d& antenna,
                                   const std::vector<int>& facades) const {
  SatelliteSignal s;
  s.satellite = constellation_.position(i, t);
  const Eigen::Vector3d to_satellite = s.satellite - antenna;
  if (Constellation::elevation(to_satellite) < params_.constellation.elevation_mask_deg * kDeg)
    return s;  // kBelowMask
  const double range = to_satellite.norm();
  if (!prisms_.blocked(facades, antenna, to_satellite / range, range)) {
    s.path = SignalPath::kLineOfSight;
    return s;
  }
  SpecularReflection echo;
  if (params_.reflections && prisms_.shortestReflection(facades, antenna, s.satellite,
                                                        params_.max_reflector_distance, echo)) {
    s.path = SignalPath::kReflected;
    s.extra_path_m = echo.extra_path_m;
    return s;
  }
  s.path = SignalPath::kBlocked;
  return s;
}

std::vector<SatelliteSignal> CanyonGnss::signals(double t, const Eigen::Vector3d& antenna) const {
  const std::vector<int> facades = facadesAround(antenna);
  std::vector<SatelliteSignal> out;
  out.reserve(constellation_.size());
  for (size_t i = 0; i < constellation_.size(); ++i) out.push_back(signal(i, t, antenna, facades));
  return out;
}

CanyonEpoch CanyonGnss::epoch(size_t k, double t, const Eigen::Vector3d& antenna) const {
  CanyonEpoch e;
  const double clock = clock_bias_m_ + clock_drift_m_s_ * t;
  // One noise stream per epoch, one draw per satellite whether used or not: a satellite's noise
  // does not depend on which others the buildings let through.
  SimRng noise(hashCombine(hashCombine(seed_, kRangeNoiseTag), k));
  std::vector<Pseudorange> ranges;
  for (const SatelliteSignal& s : signals(t, antenna)) {
    const double white = params_.range_sigma * noise.gaussian();
    if (s.path == SignalPath::kBelowMask) continue;
    if (s.path == SignalPath::kBlocked) {
      ++e.blocked;
      continue;
    }
    if (s.path == SignalPath::kReflected) {
      ++e.reflected;
      e.max_extra_path_m = std::max(e.max_extra_path_m, s.extra_path_m);
    } else {
      ++e.line_of_sight;
    }
    ranges.push_back(
        {s.satellite, (s.satellite - antenna).norm() + clock + s.extra_path_m + white});
  }
  e.fix = solvePositionFix(ranges, antenna);
  const double pdop = std::hypot(e.fix.hdop, e.fix.vdop);
  if (e.fix.valid && pdop > params_.max_pdop) e.fix.valid = false;
  if (!e.fix.valid) return e;
  e.error = e.fix.position - antenna;
  e.reported_horizontal_accuracy_m = e.fix.hdop * params_.assumed_range_sigma;
  return e;
}

CanyonDriveStats summarizeCanyonDrive(const std::vector<CanyonEpoch>& epochs, double dt) {
  CanyonDriveStats s;
  s.epochs = epochs.size();
  std::vector<double> horizontal;
  double squares = 0.0, reported = 0.0, used = 0.0, blocked = 0.0;
  for (size_t k = 0; k < epochs.size(); ++k) {
    const CanyonEpoch& e = epochs[k];
    blocked += e.blocked;
    if (!e.fix.valid) {
      s.outage_s += dt;
      if (k == 0 || epochs[k - 1].fix.valid) ++s.outages;
      continue;
    }
    const double h = e.error.head<2>().norm();
    horizontal.push_back(h);
    squares += h * h;
    reported += e.reported_horizontal_accuracy_m;
    used += e.line_of_sight + e.reflected;
    if (e.nlos()) ++s.nlos_fixes;
  }
  s.fixes = horizontal.size();
  if (s.epochs > 0) s.mean_satellites_blocked = blocked / double(s.epochs);
  if (s.fixes == 0) return s;
  const double n = double(s.fixes);
  s.horizontal_rms_m = std::sqrt(squares / n);
  s.horizontal_p95_m = percentile(horizontal, 0.95);
  s.horizontal_max_m = *std::max_element(horizontal.begin(), horizontal.end());
  for (double h : horizontal) s.horizontal_mean_m += h / n;
  s.reported_horizontal_mean_m = reported / n;
  s.nlos_fix_share = double(s.nlos_fixes) / n;
  s.mean_satellites_used = used / n;
  return s;
}

}  // namespace osm_graph_slam::sim
