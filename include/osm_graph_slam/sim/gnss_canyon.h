#pragma once
// The urban-canyon GNSS model (simulate_urban --gnss-model canyon, issue 52): a seeded
// constellation, line of sight from the antenna to every satellite against the true world's
// buildings (2.5-D prisms), blocked satellites dropped or kept with the delay of a facade
// reflection (NLOS), and the fix a receiver computes from what is left: least-squares position
// and clock, with its own optimistic accuracy (HDOP x an assumed range sigma). Every
// simplification is listed in doc/simulator.md, "Urban-canyon GNSS model".
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/sim/building_prisms.h"
#include "osm_graph_slam/sim/gnss_constellation.h"
#include "osm_graph_slam/sim/gnss_fix.h"
#include "osm_graph_slam/sim/world.h"

namespace osm_graph_slam::sim {

struct CanyonGnssParams {
  ConstellationParams constellation;
  double range_sigma = 1.5;  ///< white noise on every pseudorange [m]
  /// The receiver's assumed range error (UERE) behind its reported accuracy [m]: honest under
  /// open sky, optimistic under NLOS because the receiver cannot see the reflections.
  double assumed_range_sigma = 1.5;
  /// Facades farther from the antenna (horizontally) reflect too weakly to be tracked [m].
  double max_reflector_distance = 60.0;
  bool reflections = true;  ///< false: every blocked satellite is dropped (no NLOS)
  /// The receiver outputs no fix when the geometry is worse (u-blox's default PDOP mask).
  double max_pdop = 25.0;
  double clock_bias_max_m = 3.0e5;   ///< initial receiver clock bias, uniform in +-max [m]
  double clock_drift_max_m_s = 3.0;  ///< constant clock drift, uniform in +-max [m/s]
};

/// How one satellite reaches the antenna at one epoch.
enum class SignalPath : uint8_t { kBelowMask, kLineOfSight, kReflected, kBlocked };

struct SatelliteSignal {
  SignalPath path = SignalPath::kBelowMask;
  Eigen::Vector3d satellite = Eigen::Vector3d::Zero();  ///< ENU position [m]
  double extra_path_m = 0.0;                            ///< NLOS delay (kReflected) [m]
};

/// The receiver's output at one epoch.
struct CanyonEpoch {
  PositionFix fix;                                    ///< fix.valid false: outage
  Eigen::Vector3d error = Eigen::Vector3d::Zero();    ///< fix minus the true antenna position
  int line_of_sight = 0, reflected = 0, blocked = 0;  ///< satellites above the mask, by path
  double max_extra_path_m = 0.0;                      ///< largest NLOS delay used [m]
  /// What the receiver reports: HDOP x assumed_range_sigma, a horizontal RMS (both axes) [m].
  double reported_horizontal_accuracy_m = 0.0;
  bool nlos() const { return fix.valid && reflected > 0; }
};

class CanyonGnss {
 public:
  /// Empty if the world can drive this model, else why not: a world without buildings or with a
  /// building without a height would be a silent open sky.
  static std::string worldProblem(const World& world);

  CanyonGnss(const World& world, const CanyonGnssParams& params, uint64_t seed);
  /// With a given constellation instead of the seeded one (tests).
  CanyonGnss(const World& world, const CanyonGnssParams& params, uint64_t seed,
             Constellation constellation);

  /// The signal of every satellite to an antenna at the ENU position at time t.
  std::vector<SatelliteSignal> signals(double t, const Eigen::Vector3d& antenna) const;
  /// The receiver's fix at epoch k (time t; the epoch selects the noise stream).
  CanyonEpoch epoch(size_t k, double t, const Eigen::Vector3d& antenna) const;

  const Constellation& constellation() const { return constellation_; }
  const BuildingPrisms& prisms() const { return prisms_; }

 private:
  CanyonGnssParams params_;
  uint64_t seed_;
  Constellation constellation_;
  BuildingPrisms prisms_;
  double clock_bias_m_ = 0.0, clock_drift_m_s_ = 0.0;

  std::vector<int> facadesAround(const Eigen::Vector3d& antenna) const;
  SatelliteSignal signal(size_t satellite, double t, const Eigen::Vector3d& antenna,
                         const std::vector<int>& facades) const;
};

/// Per-drive statistics over epochs (sim_info.json).
struct CanyonDriveStats {
  size_t epochs = 0, fixes = 0, nlos_fixes = 0;
  double horizontal_rms_m = 0.0, horizontal_p95_m = 0.0, horizontal_max_m = 0.0;
  double horizontal_mean_m = 0.0;
  double reported_horizontal_mean_m = 0.0;  ///< mean HDOP x assumed sigma over the fixes
  double nlos_fix_share = 0.0;              ///< fixes with >= 1 reflected satellite / fixes
  double outage_s = 0.0;
  int outages = 0;  ///< runs of epochs without a fix
  double mean_satellites_used = 0.0, mean_satellites_blocked = 0.0;
};

CanyonDriveStats summarizeCanyonDrive(const std::vector<CanyonEpoch>& epochs, double dt);

}  // namespace osm_graph_slam::sim
