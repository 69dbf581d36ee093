#pragma once
// Platform-independent deterministic randomness for the simulator (std:: distributions differ
// between standard libraries; same seed must give the same bytes everywhere).
#include <cmath>
#include <cstdint>

namespace osm_graph_slam::sim {

/// SplitMix64 finaliser: a good 64-bit hash of x.
inline uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

inline uint64_t hashCombine(uint64_t a, uint64_t b) {
  return mix64(a ^ mix64(b));
}

/// Small counter-based generator; one per stream (per scan, per ray block, per object).
class SimRng {
 public:
  explicit SimRng(uint64_t seed) : state_(mix64(seed)) {}
  uint64_t next() { return mix64(state_ += 0x9e3779b97f4a7c15ULL); }
  /// Uniform in [0, 1).
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  int uniformInt(int lo, int hi_inclusive) {
    return lo + int(next() % uint64_t(hi_inclusive - lo + 1));
  }
  bool bernoulli(double p) { return uniform() < p; }
  /// Standard normal (Box-Muller; one value per call for simplicity).
  double gaussian() {
    const double u1 = 1.0 - uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }

 private:
  uint64_t state_;
};

}  // namespace osm_graph_slam::sim
