#pragma once
// Process-wide allocator tuning for the scan path.

namespace osm_graph_slam {

/// Keeps freed blocks of up to 32 MiB in the heap for reuse instead of handing them back to the
/// kernel. Every scan allocates a few clouds of 2-4 MB; above glibc's default mmap threshold each
/// one is a fresh mapping whose pages fault in again on first touch. Measured on the real KITTI
/// drive (2 cores, idle): prefilter 20.4 -> 6.9 ms per scan, offline_slam 19.8 -> 28.7 scans/s,
/// peak RSS +6 %. The heap also keeps 64 MiB of slack when it grows or is trimmed (M_TOP_PAD):
/// without it the same drive still took 226-258 k minor page faults (prefilter 19-22 ms), with
/// it 37-40 k (session 14). Affects the whole process; false where the C library refuses.
bool reuseFreedMemory();

}  // namespace osm_graph_slam
