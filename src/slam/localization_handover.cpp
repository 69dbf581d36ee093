#include "osm_graph_slam/slam/localization_handover.h"

#include <cmath>

namespace osm_graph_slam {
namespace {

/// Stamps of one scan as the localiser and the tracker report it (same message, same clock).
constexpr double kSameScan = 1e-3;  ///< [s]
/// Results remembered for keyframes still to come: the tracker may lag the localiser by seconds.
constexpr size_t kRemembered = 200;

}  // namespace

void LocalizationHandover::addLocalization(double stamp, bool tracking,
                                           const Eigen::Isometry3d& pose) {
  if (tracking)
    not_tracking_since_.reset();
  else if (!not_tracking_since_)
    not_tracking_since_ = stamp;
  localizations_.push_back({stamp, tracking, pose});
  if (localizations_.size() > kRemembered) localizations_.pop_front();
}

void LocalizationHandover::addKeyframe(const KeyframeInput& keyframe) {
  if (mapping())
    held_.push_back({keyframe, std::nullopt});
  else
    waiting_.push_back(keyframe);
}

std::optional<LocalizationHandover::Localization> LocalizationHandover::localizationAt(
    double stamp) const {
  for (auto it = localizations_.rbegin(); it != localizations_.rend(); ++it)
    if (std::abs(it->stamp - stamp) < kSameScan) return *it;
  return std::nullopt;
}

bool LocalizationHandover::leftTheMap(double stamp) const {
  return not_tracking_since_ && stamp - *not_tracking_since_ >= params_.leave_after;
}

void LocalizationHandover::dropOlderThanTies() {
  int tied = 0;
  for (const auto& h : held_) tied += h.localized ? 1 : 0;
  while (!held_.empty() && (tied > std::max(1, params_.ties) || !held_.front().localized)) {
    if (held_.front().localized) {
      --tied;
      ++keyframes_localized_;
    }
    last_localized_ = held_.front().keyframe.id;
    held_.pop_front();
  }
}

LocalizationHandover::Fate LocalizationHandover::fate(uint64_t id) const {
  if (first_mapped_) return id >= *first_mapped_ ? Fate::kMapped : Fate::kLocalized;
  if (last_localized_ && id <= *last_localized_) return Fate::kLocalized;
  return Fate::kWaiting;
}

std::vector<HandoverKeyframe> LocalizationHandover::release() {
  const double latest = localizations_.empty() ? -INFINITY : localizations_.back().stamp;
  // Keyframes are decided once the localiser has done their scan (it may lag the tracker).
  while (!mapping() && !waiting_.empty() && waiting_.front().stamp <= latest + kSameScan) {
    const KeyframeInput kf = waiting_.front();
    waiting_.pop_front();
    const std::optional<Localization> at = localizationAt(kf.stamp);
    if (at && at->tracking) {
      held_.push_back({kf, at->pose});
      dropOlderThanTies();
    } else {
      // Kept: it follows the last tracked keyframe, or none was tracked yet (the session then
      // starts unplaced and MapResume's own placement takes over).
      held_.push_back({kf, std::nullopt});
    }
    if (leftTheMap(kf.stamp)) handover_stamp_ = kf.stamp;
  }
  if (!mapping() && leftTheMap(latest)) handover_stamp_ = latest;
  if (mapping())
    while (!waiting_.empty()) {
      held_.push_back({waiting_.front(), std::nullopt});
      waiting_.pop_front();
    }
  if (!mapping()) return {};
  if (!first_mapped_ && !held_.empty()) first_mapped_ = held_.front().keyframe.id;
  std::vector<HandoverKeyframe> out(held_.begin(), held_.end());
  held_.clear();
  return out;
}

}  // namespace osm_graph_slam
