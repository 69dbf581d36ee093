#pragma once
// Multi-cue photometric registration (MCS-SLAM's tracker, after Della Corte et al., "A general
// framework for flexible multi-cue photometric point cloud registration", 2018): the model (a
// keyframe's multi-cue pyramid: points with normal and intensity) is moved by the current
// estimate, rendered into the current scan's image through a depth buffer, and the pixel-wise
// differences of range, intensity and normal are minimised by Gauss-Newton on SE(3), coarse to
// fine. No nearest-neighbour search: a model point is compared with the measured pixel it
// projects into (doc/multi_cue.md).
#include <Eigen/Geometry>
#include <string>

#include "osm_graph_slam/multi_cue/multi_cue_image.h"

namespace osm_graph_slam {

struct MultiCueParams {
  /// Levels of the image pyramid, coarsest first in the optimisation; 3 on a 64 x 1024 image
  /// ends at 16 x 256 (1.4 deg a column). With 2, 10 of 24 simulated 0.7 m motions failed from
  /// identity; 4 is no better.
  int pyramid_levels = 3;
  /// Render every model pixel (1) or a checkerboard half of them (2). The measured image keeps
  /// its full resolution, so each rendered point still meets its exact neighbourhood. On KITTI
  /// 0005 (doc/multi_cue.md) the agreement with GICP stayed at 0.5 cm median and Gauss-Newton
  /// took 40 % less time.
  int model_stride = 2;
  /// Gauss-Newton iterations at most on each level.
  int max_iterations_per_level = 10;
  /// Diagonal information of the cues: range [1/m^2], intensity [1/unit^2] (KITTI reflectance
  /// is in [0, 1]), normal difference (each of its 3 components).
  double range_weight = 1.0;
  double intensity_weight = 0.1;
  double normal_weight = 0.003;
  /// Robust kernel on the pixel's weighted error sqrt(e' W e): "huber" or "cauchy", and its
  /// width.
  std::string kernel = "huber";
  double kernel_width = 0.05;
  /// A pixel whose range difference exceeds this is an outlier (occlusion, moving object, a
  /// model point rendered onto another surface) and is left out [m].
  double range_gate = 1.0;
  /// The finest level stops when the Gauss-Newton step is below both [m], [rad]; level l
  /// (pixels 2^l times larger) when it is below 2^l times these. Against 1 mm / 1e-4 rad: KITTI
  /// 0005 Gauss-Newton 13.2 -> 7.5 ms per scan, agreement with GICP 0.53 -> 0.54 cm median;
  /// simulated error 0.19 -> 0.22 cm mean (doc/multi_cue.md).
  double translation_epsilon = 2e-3;
  double rotation_epsilon = 2e-4;
  /// Fewer inlier pixels than this at the finest level fails the match.
  int min_inliers = 500;
  /// Threads of the per-pixel work (gradients, linearisation); 0 = all hardware threads, as
  /// RegistrationParams::num_threads. The result does not depend on it.
  int num_threads = 0;

  /// "" when usable, else what is wrong.
  std::string validate() const;
};

struct MultiCueResult {
  /// The current scan's pose in the model's frame: p_model = transform * p_current (the
  /// convention of RegistrationResult, target = model, source = current scan).
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  bool converged = false;
  /// False when the model or the current scan carried no intensity (the cue is then off).
  bool intensity_used = false;
  int iterations = 0;  ///< Gauss-Newton iterations over all levels
  int inliers = 0;     ///< pixels used at the last iteration of the finest level
  double chi2 = 0.0;   ///< sum of e' W e over those pixels (before the kernel)
  /// J' W J at the solution for a perturbation applied on the left of `transform` in the model
  /// frame, ordered (translation, rotation), like RegistrationResult::hessian: an odometry edge's
  /// information up to the scale of counting neighbouring pixels as independent.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  double gradients_ms = 0.0;  ///< of time_ms: the measured images' cue gradients
  double time_ms = 0.0;       ///< the whole align()
  std::string message;        ///< why it failed, when it did
};

/// Residual of one model point rendered into one measured pixel, ordered (range, intensity,
/// normal x, y, z), and its Jacobian for the increment delta = (translation, rotation) applied
/// on the left of the model-to-current transform X (X <- exp(delta) X). The measured cues are
/// read at the model point's sub-pixel position through the measured image's gradients, so the
/// residual is smooth in delta while the pixel is held. Exposed for the Jacobian test.
struct CueResidual {
  Eigen::Matrix<double, 5, 1> error = Eigen::Matrix<double, 5, 1>::Zero();
  Eigen::Matrix<double, 5, 6> jacobian = Eigen::Matrix<double, 5, 6>::Zero();
  bool intensity_valid = false;
  bool normal_valid = false;
};

/// Per measured pixel, the change of each cue per pixel step along u and v, from its neighbours
/// on the same surface (MultiCueImage::kPoint pixels only; `valid` false where no neighbour
/// pair spans both directions).
struct CueGradients {
  std::vector<Eigen::Matrix<float, 5, 2>> gradient;  ///< rows: range, intensity, normal xyz
  std::vector<uint8_t> valid;
};

CueGradients computeCueGradients(const MultiCueImage& measured,
                                 const SurfaceContinuityParams& continuity);

/// The residual of model point (point, normal, intensity; normal zero when it has none) moved by
/// X into measured pixel `pixel`; false when the point does not project or the pixel has no
/// usable return or gradient.
bool cueResidual(const Eigen::Vector3f& model_point, const Eigen::Vector3f& model_normal,
                 float model_intensity, const Eigen::Isometry3d& X, const MultiCueImage& measured,
                 const CueGradients& gradients, int pixel, CueResidual* out);

class MultiCueRegistration {
 public:
  explicit MultiCueRegistration(const MultiCueParams& params,
                                const SurfaceContinuityParams& continuity = {});

  /// Aligns the current scan's pyramid to the model's, from `guess` (the current scan's pose in
  /// the model frame). Both pyramids must come from the same projection. The intensity cue is
  /// used only when both carry intensity. Never throws: converged = false and a message instead.
  MultiCueResult align(const MultiCuePyramid& model, const MultiCuePyramid& current,
                       const Eigen::Isometry3d& guess) const;

  const MultiCueParams& params() const { return params_; }

 private:
  MultiCueParams params_;
  SurfaceContinuityParams continuity_;
};

}  // namespace osm_graph_slam
