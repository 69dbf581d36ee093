#pragma once
// Process-wide allocator tuning for the scan path.

namespace osm_graph_slam {

/// Keeps freed blocks of up to 32 MiB in the heap for reuse instead of handing them back to the
/// kernel. Every scan allocates a few clouds of 2-4 MB; above glibc's default mmap threshold each
/// one is a fresh mapping whose pages fault in again on first touch. The heap also keeps 64 MiB
/// of slack when it grows or is trimmed (M_TOP_PAD). Measured on the real KITTI drive (2 cores,
/// idle, doc/real_data.md "Throughput"): 254 k -> 41 k minor page faults per run, prefilter about
/// 20 -> 10 ms per scan. Affects the whole process; false where the C library refuses.
bool reuseFreedMemory();

}  // namespace osm_graph_slam
