#include "osm_graph_slam/radar/radar_stream.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "osm_graph_slam/common/param_reader.h"

namespace osm_graph_slam::radar {

bool readParams(const ParamReader& r, RadarStreamParams& p, std::string* error) {
  r.param("input/azimuths", p.layout.expected_azimuths);
  r.param("input/bins", p.layout.expected_bins);
  r.param("input/range_resolution", p.layout.range_resolution);
  r.param("input/rotation_period", p.layout.rotation_period);
  r.param("input/max_gap", p.max_gap);
  r.param("input/gnss_unknown_sigma", p.gnss_unknown_sigma);
  r.param("input/nav_buffer", p.nav_buffer);
  if (p.layout.expected_azimuths <= 0 || p.layout.expected_bins <= 0 ||
      !(p.layout.range_resolution > 0.0) || !(p.layout.rotation_period > 0.0) ||
      !(p.max_gap > 0.0) || !(p.gnss_unknown_sigma > 0.0) || !(p.nav_buffer >= 0.0)) {
    if (error)
      *error =
          "radar parameters: input/azimuths, input/bins, input/range_resolution, "
          "input/rotation_period, input/max_gap and input/gnss_unknown_sigma must be > 0, "
          "input/nav_buffer >= 0";
    return false;
  }
  return true;
}

namespace {
// Navigation data held before the first sweep, at most (40 s of a 100 Hz IMU with 10 Hz fixes);
// the oldest beyond it is dropped (counted): it is older than nav_buffer before any sweep to come.
constexpr size_t kMaxPendingNav = 4096;
}  // namespace

const char* toString(RadarStreamEvent event) {
  switch (event) {
    case RadarStreamEvent::kProcessed:
      return "processed";
    case RadarStreamEvent::kRestarted:
      return "restarted";
    case RadarStreamEvent::kBadImage:
      return "bad_image";
    case RadarStreamEvent::kOutOfOrder:
      return "out_of_order";
  }
  return "unknown";
}

RadarStreamResult RadarOdometryStream::process(const PolarImageView& image, int64_t stamp_ns) {
  const auto t0 = std::chrono::steady_clock::now();
  RadarStreamResult result;
  ++counters_.received;
  if (has_last_ && stamp_ns <= last_stamp_ns_) {
    result.event = RadarStreamEvent::kOutOfOrder;
    char text[160];
    std::snprintf(text, sizeof(text),
                  "sweep stamped %.6f s is not newer than the last one (%.6f s): dropped",
                  double(stamp_ns) * 1e-9, double(last_stamp_ns_) * 1e-9);
    result.message = text;
    ++counters_.out_of_order;
    return result;
  }
  if (!has_last_) origin_ns_ = stamp_ns;
  MulranPolarResult converted =
      fromMulranImage(image, double(stamp_ns - origin_ns_) * 1e-9, params_.layout);
  if (!converted.ok) {
    result.event = RadarStreamEvent::kBadImage;
    result.message = converted.error;
    ++counters_.bad_images;
    return result;
  }
  result.event = RadarStreamEvent::kProcessed;
  if (has_last_) {
    const double gap = double(stamp_ns - last_stamp_ns_) * 1e-9;
    if (gap > params_.max_gap) {
      slam_.restart();
      ++counters_.gaps;
      result.event = RadarStreamEvent::kRestarted;
      char text[200];
      std::snprintf(text, sizeof(text),
                    "%.3f s since the last sweep (max_gap %.3f s): odometry restarted with zero "
                    "velocity, the motion during the gap is not known",
                    gap, params_.max_gap);
      result.message = text;
    }
  }
  if (!has_last_) {
    // The first sweep fixes the clock: hand over what waited for it, in arrival order, without
    // what is more than nav_buffer older than the sweep.
    const int64_t oldest = origin_ns_ - std::llround(params_.nav_buffer * 1e9);
    for (const PendingNav& nav : pending_) {
      if (nav.stamp_ns < oldest) {
        ++counters_.nav_dropped_early;
        continue;
      }
      ++counters_.nav_buffered;
      handOver(nav);
    }
    pending_.clear();
  }
  has_last_ = true;
  last_stamp_ns_ = stamp_ns;
  const size_t loops_before = slam_.loops().size();
  const bool anchored_before = slam_.navStats().anchored;
  const int optimisations_before = slam_.loopStats().optimisations;
  result.step = slam_.process(converted.scan);
  result.has_step = true;
  result.time_ns = toInputTime(result.step.time);
  result.new_loops = int(slam_.loops().size() - loops_before);
  result.new_anchor = slam_.navStats().anchored && !anchored_before;
  result.optimised = slam_.loopStats().optimisations != optimisations_before;
  result.map_to_odometry = slam_.mapToOdometry();
  result.corrected = result.map_to_odometry * result.step.pose;
  ++counters_.processed;
  if (!result.step.ok) ++counters_.ransac_failures;
  counters_.ms_last =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  counters_.ms_mean += (counters_.ms_last - counters_.ms_mean) / double(counters_.processed);
  const RadarLoopStats& ls = slam_.loopStats();
  if (ls.keyframes_searched > 0)
    counters_.ms_loop_per_keyframe =
        (ls.ms_descriptor + ls.ms_search + ls.ms_verify + ls.ms_optimise) /
        double(ls.keyframes_searched);
  return result;
}

int64_t RadarOdometryStream::toInputTime(double time) const {
  return origin_ns_ + std::llround(time * 1e9);
}

void RadarOdometryStream::addGnssFix(int64_t stamp_ns, double lat, double lon, double alt,
                                     double sigma, bool valid) {
  ++counters_.gnss_received;
  if (!loops_enabled_) {
    ++counters_.nav_ignored;
    return;
  }
  if (!valid || !std::isfinite(lat) || !std::isfinite(lon) || std::abs(lat) > 90.0 ||
      std::abs(lon) > 180.0) {
    ++counters_.gnss_invalid;
    return;
  }
  if (!(sigma >= 0.0)) {  // negative (unknown covariance) or NaN
    sigma = params_.gnss_unknown_sigma;
    ++counters_.gnss_unknown_sigma;
  }
  if (!enu_) enu_.emplace(lat, lon, std::isfinite(alt) ? alt : 0.0);
  if (!std::isfinite(alt)) alt = enu_->originAlt();
  const Eigen::Vector3d p = enu_->toEnu(lat, lon, alt);
  PendingNav nav;
  nav.stamp_ns = stamp_ns;
  nav.fix = true;
  nav.value = Eigen::Vector3d(p.x(), p.y(), sigma);
  if (has_last_)
    handOver(nav);
  else
    holdForFirstSweep(nav);
}

void RadarOdometryStream::addYawRate(int64_t stamp_ns, double rate, bool available) {
  ++counters_.imu_received;
  if (!loops_enabled_) {
    ++counters_.nav_ignored;
    return;
  }
  if (!available || !std::isfinite(rate)) {
    ++counters_.imu_invalid;
    return;
  }
  PendingNav nav;
  nav.stamp_ns = stamp_ns;
  nav.value.x() = rate;
  if (has_last_)
    handOver(nav);
  else
    holdForFirstSweep(nav);
}

void RadarOdometryStream::handOver(const PendingNav& nav) {
  const double time = double(nav.stamp_ns - origin_ns_) * 1e-9;
  if (nav.fix)
    slam_.addGnssFix(time, nav.value.head<2>(), nav.value.z());
  else
    slam_.addYawRate(time, nav.value.x());
}

void RadarOdometryStream::holdForFirstSweep(const PendingNav& nav) {
  pending_.push_back(nav);
  if (pending_.size() > kMaxPendingNav) {
    pending_.pop_front();
    ++counters_.nav_dropped_early;
  }
}

}  // namespace osm_graph_slam::radar
