#include "osm_graph_slam/common/memory_tuning.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace osm_graph_slam {

bool reuseFreedMemory() {
#if defined(__GLIBC__)
  // 32 MiB is glibc's largest mmap threshold on 64-bit; trimming waits for 4x that of free top.
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 128 * 1024 * 1024) == 1;
  return mmap_ok && trim_ok;
#else
  return false;
#endif
}

}  // namespace osm_graph_slam
