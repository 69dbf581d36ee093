#include "scan_matcher.h"

#include <pcl/common/transforms.h>

#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "osm_graph_slam/multi_cue/multi_cue_image.h"
#include "osm_graph_slam/multi_cue/multi_cue_registration.h"

namespace osm_graph_slam {
namespace {

/// The transform with its rotation made orthonormal again. The tracker composes every match
/// onto its pose and feeds the pose back as the next guess; Isometry3d's inverse is a transpose,
/// so a rotation slightly off orthonormal grew by a factor of ~3 per scan through that loop (on
/// KITTI 0005: 1e-16 at the start, 3e-3 after 28 scans, then the track diverged).
Eigen::Isometry3d orthonormal(const Eigen::Isometry3d& t) {
  Eigen::Isometry3d out = t;
  out.linear() = Eigen::Quaterniond(t.linear()).normalized().toRotationMatrix();
  return out;
}

/// The projection preset named by `sensor`; "auto" decides on the first scan: an HDL-64E sees up to
/// +2 deg of elevation, an OS1-64 up to +16.6 deg, so a scan with more than 1 % of its returns
/// above +5 deg is an OS1-64's. (The simulator's drives have both sensors under one config.)
std::string presetFor(const std::string& sensor, const PointCloud& scan) {
  if (sensor != "auto") return sensor;
  const double tan_5deg = std::tan(5.0 * M_PI / 180.0);
  size_t above = 0, valid = 0;
  for (const auto& p : scan.points) {
    const double rho = std::hypot(p.x, p.y);
    if (!std::isfinite(rho) || rho < 2.0) continue;
    ++valid;
    above += p.z > tan_5deg * rho;
  }
  return above > 0.01 * valid ? "os1_64" : "hdl64e";
}

/// GICP (or the other `registration_method`s) on the prefiltered scan against the graph
/// keyframe: the tracker as it always was.
class GicpMatcher : public ScanMatcher {
 public:
  explicit GicpMatcher(const RegistrationParams& params)
      : registration_(createRegistration(params)) {}

  void setReference(const MatcherScan& scan) override { registration_->setTarget(scan.cloud); }
  RegistrationResult align(const MatcherScan& scan, const Eigen::Isometry3d& guess) override {
    return registration_->align(scan.cloud, guess);
  }
  bool wantsReference(const Eigen::Isometry3d&) const override { return false; }
  bool registrationIsEdge() const override { return true; }

 private:
  std::unique_ptr<Registration> registration_;
};

/// MCS-SLAM's tracker registration: the scan's multi-cue pyramid, built in the LiDAR's frame
/// (the spherical image is the sensor's view), against the reference's pyramid.
class MultiCueMatcher : public ScanMatcher {
 public:
  explicit MultiCueMatcher(const MultiCueTrackingParams& params)
      : params_(params), registration_(params.registration, params.continuity) {}

  void setReference(const MatcherScan& scan) override { reference_ = pyramidOf(scan); }

  RegistrationResult align(const MatcherScan& scan, const Eigen::Isometry3d& guess) override {
    RegistrationResult out;
    if (!reference_) {
      out.message = "no reference scan";
      return out;
    }
    // The registration works between the two sensor frames; the tracker's poses are base_link's.
    const Eigen::Isometry3d& s = scan.sensor_to_base;
    const MultiCueResult r =
        registration_.align(*reference_, *pyramidOf(scan), orthonormal(s.inverse() * guess * s));
    out.transform = orthonormal(s * r.transform * s.inverse());
    out.converged = r.converged;
    // The mean weighted squared cue error per pixel, so that the fitness gate can notice a
    // match in the wrong basin; its limits are MultiCueTrackingParams', not GICP's.
    out.fitness = r.inliers > 0 ? r.chi2 / r.inliers : std::numeric_limits<double>::infinity();
    // No Hessian: registrationIsEdge() is false, the back-end weighs the edge by its model.
    out.iterations = r.iterations;
    out.time_ms = r.time_ms;
    out.message = r.message;
    return out;
  }

  bool wantsReference(const Eigen::Isometry3d& relative) const override {
    return relative.translation().norm() >= params_.keyframe_delta_trans ||
           Eigen::AngleAxisd(relative.linear()).angle() >= params_.keyframe_delta_angle;
  }
  bool registrationIsEdge() const override { return false; }

  std::string takeNotice() override {
    std::string out;
    out.swap(notice_);
    return out;
  }

 private:
  /// The scan's pyramid, built once per scan: the recovery's retries and the scan becoming the
  /// reference reuse it (keyed by the cloud object, kept alive so its address is not reused).
  std::shared_ptr<const MultiCuePyramid> pyramidOf(const MatcherScan& scan) {
    const PointCloudConstPtr& key = scan.sensor_scan ? scan.sensor_scan : scan.cloud;
    if (key == cached_key_ && cached_) return cached_;
    PointCloud moved;
    if (!scan.sensor_scan) {
      // A 0.5 m voxel cloud fills a fraction of the image: it tracks, less accurately.
      note(no_sensor_scan_noted_,
           "multi_cue tracker: no full-resolution scan given, projecting the prefiltered cloud "
           "(a sparse image: less accurate)");
      pcl::transformPointCloud(*scan.cloud, moved,
                               scan.sensor_to_base.inverse().matrix().cast<float>());
    }
    const PointCloud& in_sensor = scan.sensor_scan ? *scan.sensor_scan : moved;
    if (!projection_) {
      const std::string preset = presetFor(params_.sensor, in_sensor);
      projection_ = preset == "os1_64" ? SphericalProjectionParams::os1_64()
                                       : SphericalProjectionParams::hdl64e();
      if (params_.sensor == "auto")
        note(sensor_noted_, "multi_cue tracker: multi_cue_sensor auto: " + preset + " projection");
    }
    auto pyramid = std::make_shared<MultiCuePyramid>(
        buildPyramid(in_sensor, *projection_, params_.registration.pyramid_levels,
                     params_.continuity, nullptr, params_.registration.num_threads));
    if (!pyramid->has_intensity())
      note(no_intensity_noted_,
           "multi_cue tracker: the scans carry no intensity (every value zero or missing): "
           "the intensity cue is off");
    cached_key_ = key;
    cached_ = pyramid;
    return pyramid;
  }

  void note(bool& given, const std::string& text) {
    if (given) return;
    given = true;
    notice_ += (notice_.empty() ? "" : "; ") + text;
  }

  MultiCueTrackingParams params_;
  std::optional<SphericalProjectionParams> projection_;  ///< from the first scan with "auto"
  MultiCueRegistration registration_;
  std::shared_ptr<const MultiCuePyramid> reference_;
  PointCloudConstPtr cached_key_;
  std::shared_ptr<const MultiCuePyramid> cached_;
  std::string notice_;
  bool no_intensity_noted_ = false, no_sensor_scan_noted_ = false, sensor_noted_ = false;
};

}  // namespace

std::unique_ptr<ScanMatcher> createScanMatcher(const KeyframeTrackerParams& params) {
  if (const std::string why = params.validate(); !why.empty()) throw std::invalid_argument(why);
  if (params.tracker == "multi_cue") return std::make_unique<MultiCueMatcher>(params.multi_cue);
  return std::make_unique<GicpMatcher>(params.registration);
}

}  // namespace osm_graph_slam
