#include "osm_graph_slam/osm/osm_buffer.h"

#include <algorithm>
#include <sstream>

namespace osm_graph_slam {
namespace {

std::string formatPosition(const Eigen::Vector2d& p) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(1);
  s << "(" << p.x() << ", " << p.y() << ")";
  return s.str();
}

}  // namespace

OsmBuffer::OsmBuffer(std::shared_ptr<OsmMapSource> source, const EnuConverter& enu,
                     const OsmBufferParams& params, std::shared_ptr<const Logger> logger)
    : source_(std::move(source)),
      enu_(enu),
      params_(params),
      logger_(logger ? std::move(logger) : std::make_shared<const Logger>()),
      retry_wait_s_(params.retry_initial_s) {
  worker_ = std::thread([this] { workerLoop(); });
}

OsmBuffer::~OsmBuffer() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  if (source_) source_->cancel();  // do not wait for a slow server at shutdown
  request_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

OsmQueryResult OsmBuffer::query(const Eigen::Vector2d& position) {
  return query(position, params_.query_radius);
}

OsmQueryResult OsmBuffer::query(const Eigen::Vector2d& position, double radius) {
  std::shared_ptr<const Snapshot> snap;
  OsmQueryResult result;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    snap = snapshot_;
    if (!snap || (position - snap->centre).norm() > params_.refresh_distance) {
      requestLocked(position, false);
    }
    result.refill_in_flight = in_flight_ || pending_.has_value();
  }
  if (!snap) return result;
  // Filtering runs on the immutable snapshot outside the lock: a finishing refill never
  // waits for a query and a query never waits for a refill.
  result.buffer_valid = true;
  result.generation = snap->generation;
  result.buffer_centre = snap->centre;
  for (const Building& b : snap->buildings) {
    if (outlineDistance(b.outline_enu, position) <= radius) result.buildings.push_back(b);
  }
  warnCoverage(*snap, position, radius);
  return result;
}

void OsmBuffer::warnCoverage(const Snapshot& snap, const Eigen::Vector2d& position,
                             double radius) const {
  const double reach = (position - snap.centre).norm() + radius;
  const std::string key = "osm_buffer/coverage";
  if (reach > params_.buffer_radius) {
    logger_->warnOnce(key, "OSM buffer: query at " + formatPosition(position) + " reaches " +
                               std::to_string(static_cast<int>(reach)) +
                               " m from the buffer centre " + formatPosition(snap.centre) +
                               ", beyond its " +
                               std::to_string(static_cast<int>(params_.buffer_radius)) +
                               " m radius: buildings may be missing until a refill succeeds");
  } else {
    logger_->resetOnce(key);
  }
}

bool OsmBuffer::requestLocked(const Eigen::Vector2d& position, bool ignore_backoff) {
  if (in_flight_ || pending_ || stop_) return false;
  if (!ignore_backoff && Clock::now() < next_retry_) return false;
  pending_ = position;
  request_cv_.notify_one();
  return true;
}

bool OsmBuffer::fillBlocking(const Eigen::Vector2d& position, double timeout_s) {
  uint64_t before;
  size_t failed_before;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                      [this] { return !in_flight_ && !pending_; });
    before = stats_.generation;
    failed_before = stats_.fills_failed;
    if (!requestLocked(position, true)) return false;
  }
  if (!waitForIdle(timeout_s)) return false;
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_.generation > before && stats_.fills_failed == failed_before;
}

bool OsmBuffer::waitForIdle(double timeout_s) const {
  std::unique_lock<std::mutex> lock(mutex_);
  return idle_cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                           [this] { return !in_flight_ && !pending_; });
}

OsmBufferStats OsmBuffer::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  OsmBufferStats s = stats_;
  s.refill_in_flight = in_flight_ || pending_.has_value();
  return s;
}

void OsmBuffer::workerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    request_cv_.wait(lock, [this] { return stop_ || pending_.has_value(); });
    if (stop_) break;
    const Eigen::Vector2d centre = *pending_;
    pending_.reset();
    in_flight_ = true;
    lock.unlock();
    const MapFetchResult result = source_->fetch(enu_.toGeoPoint(centre), params_.buffer_radius);
    handleResult(centre, result);
    lock.lock();
    in_flight_ = false;
    idle_cv_.notify_all();
  }
  pending_.reset();
  idle_cv_.notify_all();
}

void OsmBuffer::handleResult(const Eigen::Vector2d& centre, MapFetchResult result) {
  if (!result.ok) {
    const std::string kind = result.error_kind.empty() ? "unknown" : result.error_kind;
    double wait_s;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.fills_failed;
      ++stats_.consecutive_failures;
      stats_.last_error = result.error;
      wait_s = retry_wait_s_;
      next_retry_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                       std::chrono::duration<double>(wait_s));
      retry_wait_s_ = std::min(params_.retry_max_s, retry_wait_s_ * params_.retry_factor);
      failure_keys_.insert("osm_buffer/" + kind);
    }
    std::ostringstream msg;
    msg << "OSM buffer: refill around " << formatPosition(centre) << " from " << source_->describe()
        << " failed [" << kind << "]: " << result.error
        << "; keeping the current buffer, retrying in " << wait_s << " s";
    logger_->warnOnce("osm_buffer/" + kind, msg.str());
    return;
  }

  auto snap = std::make_shared<Snapshot>();
  snap->centre = centre;
  snap->buildings = std::move(result.buildings);
  for (Building& b : snap->buildings) enu_.project(b);

  std::set<std::string> cleared;
  size_t failures;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    snap->generation = ++stats_.generation;
    failures = stats_.consecutive_failures;
    stats_.has_data = true;
    stats_.buildings = snap->buildings.size();
    stats_.centre = centre;
    ++stats_.fills_ok;
    stats_.consecutive_failures = 0;
    stats_.last_fetch_s = result.elapsed_s;
    snapshot_ = snap;
    next_retry_ = Clock::time_point::min();
    retry_wait_s_ = params_.retry_initial_s;
    cleared.swap(failure_keys_);
  }
  for (const std::string& key : cleared) logger_->resetOnce(key);
  std::ostringstream msg;
  msg << "OSM buffer: " << snap->buildings.size() << " buildings within " << params_.buffer_radius
      << " m of " << formatPosition(centre) << " from " << source_->describe() << " in "
      << static_cast<int>(result.elapsed_s * 1000.0) << " ms";
  if (failures > 0) msg << " (recovered after " << failures << " failed attempts)";
  logger_->info(msg.str());
}

}  // namespace osm_graph_slam
