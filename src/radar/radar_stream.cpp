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
  if (p.layout.expected_azimuths <= 0 || p.layout.expected_bins <= 0 ||
      !(p.layout.range_resolution > 0.0) || !(p.layout.rotation_period > 0.0) ||
      !(p.max_gap > 0.0)) {
    if (error)
      *error =
          "radar parameters: input/azimuths, input/bins, input/range_resolution, "
          "input/rotation_period and input/max_gap must be > 0";
    return false;
  }
  return true;
}

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
  has_last_ = true;
  last_stamp_ns_ = stamp_ns;
  const size_t loops_before = slam_.loops().size();
  result.step = slam_.process(converted.scan);
  result.has_step = true;
  result.time_ns = toInputTime(result.step.time);
  result.new_loops = int(slam_.loops().size() - loops_before);
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

}  // namespace osm_graph_slam::radar
