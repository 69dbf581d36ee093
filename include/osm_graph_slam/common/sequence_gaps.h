#pragma once
// Counts ids that never arrived in a stream that numbers its messages 0, 1, 2, ... (keyframes):
// a subscriber whose queue overflowed loses messages without any error, this makes it visible.
#include <cstdint>
#include <optional>
#include <string>

namespace osm_graph_slam {

class SequenceGaps {
 public:
  /// Ids skipped just before `id` (0: none). An id not newer than the last one (a duplicate, an
  /// out-of-order message) is not a gap and does not move the last id.
  uint64_t observe(uint64_t id) {
    uint64_t gap = 0;
    if (last_ && id > *last_ + 1) {
      gap = id - *last_ - 1;
      missing_ += gap;
      last_gap_ = "ids " + std::to_string(*last_ + 1) + ".." + std::to_string(id - 1);
    }
    if (!last_ || id > *last_) last_ = id;
    return gap;
  }
  /// The stream restarts its numbering at id (a new session): nothing before it is missing.
  void restartAt(uint64_t id) { last_ = id; }
  uint64_t missing() const { return missing_; }
  /// "ids a..b" of the latest gap, for a log line.
  const std::string& lastGap() const { return last_gap_; }

 private:
  std::optional<uint64_t> last_;
  uint64_t missing_ = 0;
  std::string last_gap_;
};

}  // namespace osm_graph_slam
