#include "osm_graph_slam/common/memory_tuning.h"

#include <cstdlib>  // defines __GLIBC__ (features.h); without a libc header the #if below is always false

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace osm_graph_slam {

bool reuseFreedMemory() {
#if defined(__GLIBC__)
  // 32 MiB is glibc's largest mmap threshold on 64-bit; trimming waits for 4x that of free top.
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 128 * 1024 * 1024) == 1;
  // Without a pad, a trim hands back everything above the top chunk and the heap grows by exactly
  // the next request again, so the pages of a scan's clouds fault in anew after every trim.
  const bool pad_ok = mallopt(M_TOP_PAD, 64 * 1024 * 1024) == 1;
  return mmap_ok && trim_ok && pad_ok;
#else
  return false;
#endif
}

}  // namespace osm_graph_slam
