#include "osm_graph_slam/sim/nav_errors.h"

#include <cmath>

#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;

/// Stream tags (ASCII) so that each error kind draws from its own generator.
constexpr uint64_t kGnssWhiteTag = 0x676e73735f77ULL;  // "gnss_w"
constexpr uint64_t kGnssBiasTag = 0x676e73735f62ULL;   // "gnss_b"
constexpr uint64_t kOutageTag = 0x6f7574616765ULL;     // "outage"
constexpr uint64_t kAttitudeTag = 0x617474697475ULL;   // "attitu"
constexpr uint64_t kImuTag = 0x696d755f6e7aULL;        // "imu_nz"
constexpr uint64_t kGyroBiasTag = 0x6779726f5f62ULL;   // "gyro_b"

Eigen::Vector3d gaussian3(SimRng& rng, double sx, double sy, double sz) {
  const double x = rng.gaussian(), y = rng.gaussian(), z = rng.gaussian();
  return Eigen::Vector3d(sx * x, sy * y, sz * z);
}

double wrapAngle(double a) {
  return std::atan2(std::sin(a), std::cos(a));
}

}  // namespace

NavErrorSequence simulateNavErrors(const NavErrorParams& p, uint64_t seed, double dt,
                                   const std::vector<double>& path_length) {
  NavErrorSequence out;
  const size_t n = path_length.size();
  out.epochs.resize(n);
  if (p.rtk || n == 0) return out;

  // GNSS: white noise plus a first-order Gauss-Markov bias per axis, started in its stationary
  // distribution: b_k = phi b_{k-1} + sigma sqrt(1 - phi^2) w_k, phi = exp(-dt / tau).
  SimRng white(hashCombine(seed, kGnssWhiteTag)), bias_rng(hashCombine(seed, kGnssBiasTag));
  const double phi = p.gnss_bias_tau_s > 0.0 ? std::exp(-dt / p.gnss_bias_tau_s) : 0.0;
  const double drive = std::sqrt(std::max(0.0, 1.0 - phi * phi));
  const double bh = p.gnss_bias_sigma, bv = p.gnss_bias_sigma_vertical;
  Eigen::Vector3d bias = gaussian3(bias_rng, bh, bh, bv);
  for (size_t k = 0; k < n; ++k) {
    if (k > 0) bias = phi * bias + drive * gaussian3(bias_rng, bh, bh, bv);
    out.epochs[k].gnss_bias = bias;
    out.epochs[k].gnss = bias + gaussian3(white, p.gnss_sigma, p.gnss_sigma, p.gnss_sigma_vertical);
  }

  // Outages: starts a Poisson process along the path (exponential gaps in metres, counted from
  // the end of the previous outage), none before gnss_outage_min_start_s.
  if (p.gnss_outages_per_km > 0.0 && p.gnss_outage_duration_s > 0.0) {
    SimRng rng(hashCombine(seed, kOutageTag));
    auto gap = [&] { return -std::log(1.0 - rng.uniform()) / p.gnss_outages_per_km * 1000.0; };
    double next_start = gap();
    size_t k = 0;
    while (k < n) {
      const double t = double(k) * dt;
      if (t < p.gnss_outage_min_start_s || path_length[k] < next_start) {
        ++k;
        continue;
      }
      ++out.outages;
      while (k < n && double(k) * dt < t + p.gnss_outage_duration_s - 1e-9)
        out.epochs[k++].outage = true;
      next_start = path_length[k - 1] + gap();
    }
  }

  // INS attitude: white roll/pitch/yaw noise and a constant heading bias of fixed magnitude
  // whose sign is drawn once per drive.
  SimRng att(hashCombine(seed, kAttitudeTag));
  out.heading_bias = (att.bernoulli(0.5) ? 1.0 : -1.0) * p.imu_heading_bias_deg * kDeg;
  SimRng imu(hashCombine(seed, kImuTag));
  const double sa = p.imu_attitude_sigma_deg * kDeg, sy = p.imu_heading_sigma_deg * kDeg;
  const double sg = p.gyro_sigma_deg_s * kDeg;
  SimRng gyro_bias(hashCombine(seed, kGyroBiasTag));  // its own stream: other draws unchanged
  out.gyro_bias_z = (gyro_bias.bernoulli(0.5) ? 1.0 : -1.0) * p.gyro_bias_deg_s * kDeg;
  for (auto& e : out.epochs) {
    const Eigen::Vector3d a = gaussian3(att, sa, sa, sy);
    e.roll = a.x();
    e.pitch = a.y();
    e.yaw = out.heading_bias + a.z();
    e.gyro = gaussian3(imu, sg, sg, sg) + Eigen::Vector3d(0, 0, out.gyro_bias_z);
    e.accel = gaussian3(imu, p.accel_sigma, p.accel_sigma, p.accel_sigma);
  }
  return out;
}

bool parseGnssModel(const std::string& name, NavErrorParams& p) {
  if (name != "noisy" && name != "rtk" && name != "canyon") return false;
  p.rtk = name == "rtk";
  p.gnss_model = name == "canyon" ? GnssPositionModel::kCanyon : GnssPositionModel::kNoisy;
  return true;
}

const char* gnssModelName(const NavErrorParams& p) {
  if (p.rtk) return "rtk";
  return p.gnss_model == GnssPositionModel::kCanyon ? "canyon" : "noisy";
}

void applyCanyonFixes(const std::vector<CanyonEpoch>& fixes, NavErrorSequence& sequence) {
  sequence.outages = 0;
  for (size_t k = 0; k < sequence.epochs.size() && k < fixes.size(); ++k) {
    NavEpochError& e = sequence.epochs[k];
    const CanyonEpoch& fix = fixes[k];
    e.outage = !fix.fix.valid;
    e.gnss = e.outage ? Eigen::Vector3d::Zero() : fix.error;
    e.gnss_bias = Eigen::Vector3d::Zero();
    e.reported_accuracy = fix.reported_horizontal_accuracy_m / std::sqrt(2.0);
    e.satellites_used = fix.line_of_sight + fix.reflected;
    if (e.outage && (k == 0 || fixes[k - 1].fix.valid)) ++sequence.outages;
  }
}

double gnssReportedAccuracy(const NavErrorParams& p) {
  return std::hypot(p.gnss_sigma, p.gnss_bias_sigma);
}

OxtsRecord measuredOxtsRecord(const OxtsRecord& truth, const Eigen::Vector3d& fix_enu,
                              const NavEpochError& e, const NavErrorParams& p,
                              const EnuConverter& enu) {
  if (p.rtk) return truth;
  OxtsRecord r = truth;
  const Eigen::Vector3d geo = enu.toGeodetic(fix_enu);
  r.lat = geo.x();
  r.lon = geo.y();
  r.alt = geo.z();
  r.roll = truth.roll + e.roll;
  r.pitch = truth.pitch + e.pitch;
  r.yaw = wrapAngle(truth.yaw + e.yaw);
  r.wx += e.gyro.x();
  r.wy += e.gyro.y();
  r.wz += e.gyro.z();
  r.wf += e.gyro.x();
  r.wl += e.gyro.y();
  r.wu += e.gyro.z();
  r.ax += e.accel.x();
  r.ay += e.accel.y();
  r.az += e.accel.z();
  r.af += e.accel.x();
  r.al += e.accel.y();
  r.au += e.accel.z();
  if (e.outage) {
    r.pos_accuracy = kOxtsNoFixAccuracy;
    r.numsats = 0;
    r.posmode = 0;  // OXTS position mode "none"
    r.velmode = 0;
  } else {
    r.pos_accuracy =
        std::isnan(e.reported_accuracy) ? gnssReportedAccuracy(p) : e.reported_accuracy;
    r.numsats = e.satellites_used >= 0 ? e.satellites_used : 8;
    r.posmode = 3;  // single-point positioning, no differential corrections
    r.velmode = 3;
  }
  return r;
}

}  // namespace osm_graph_slam::sim
