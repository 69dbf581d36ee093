#include "osm_graph_slam/multi_cue/multi_cue_registration.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "osm_graph_slam/common/timing.h"

namespace osm_graph_slam {

namespace {

using Clock = std::chrono::steady_clock;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

template <typename Scalar = double>
Eigen::Matrix<Scalar, 3, 3> skew(const Eigen::Matrix<Scalar, 3, 1>& v) {
  Eigen::Matrix<Scalar, 3, 3> m;
  m << Scalar(0), -v.z(), v.y(), v.z(), Scalar(0), -v.x(), -v.y(), v.x(), Scalar(0);
  return m;
}

/// The increment X <- exp(delta) X: rotate by the rotation vector, then translate.
Eigen::Isometry3d applyIncrement(const Vector6d& delta, const Eigen::Isometry3d& X) {
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d omega = delta.tail<3>();
  const double angle = omega.norm();
  if (angle > 0.0) step.linear() = Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
  step.translation() = delta.head<3>();
  return step * X;
}

/// Continuous pixel coordinates of q in double precision (the float projection's formula), for
/// the residual whose derivatives must stay smooth at small increments.
Eigen::Vector2d pixelOf(const SphericalProjectionParams& projection, const Eigen::Vector3d& q) {
  double azimuth = std::atan2(q.y(), q.x()) - projection.azimuth_start;
  if (azimuth < 0.0) azimuth += 2.0 * M_PI;
  if (azimuth >= 2.0 * M_PI) azimuth -= 2.0 * M_PI;
  const double elevation = std::atan2(q.z(), std::hypot(q.x(), q.y()));
  return {azimuth * projection.colsPerRadian(),
          (projection.elevation_max - elevation) * projection.rowsPerRadian()};
}

/// The sub-pixel offset of `at` from the measured return's own position, with the azimuth wrapped
/// on a full circle.
template <typename Scalar>
Eigen::Matrix<Scalar, 2, 1> offsetFrom(const SphericalProjectionParams& projection,
                                       const Eigen::Matrix<Scalar, 2, 1>& at,
                                       const Eigen::Vector2f& measured) {
  Eigen::Matrix<Scalar, 2, 1> d = at - measured.cast<Scalar>();
  if (projection.fullCircle()) {
    const Scalar cols = static_cast<Scalar>(projection.cols);
    if (d.x() > Scalar(0.5) * cols) d.x() -= cols;
    if (d.x() < Scalar(-0.5) * cols) d.x() += cols;
  }
  return d;
}

Eigen::Matrix<float, 5, 1> cuesAt(const MultiCueImage& image, int i) {
  Eigen::Matrix<float, 5, 1> c;
  c << image.range[i], image.intensity[i], image.normal[i];
  return c;
}

bool onOneSurface(float range_a, float range_b, double max_jump_ratio) {
  return std::abs(range_a - range_b) < max_jump_ratio * std::min(range_a, range_b);
}

/// Least-squares gradient of the 5 cues at pixel i from its same-surface 4-neighbours; false
/// unless they span both image directions.
bool gradientAt(const MultiCueImage& image, int i, double max_jump_ratio,
                Eigen::Matrix<float, 5, 2>* gradient) {
  const int rows = image.rows(), cols = image.cols();
  const int row = i / cols, col = i % cols;
  const bool wraps = image.projection.fullCircle();
  int neighbours[4] = {col > 0 ? i - 1 : (wraps ? image.index(row, cols - 1) : -1),
                       col + 1 < cols ? i + 1 : (wraps ? image.index(row, 0) : -1),
                       row > 0 ? i - cols : -1, row + 1 < rows ? i + cols : -1};
  Eigen::Matrix2f DDt = Eigen::Matrix2f::Zero();
  Eigen::Matrix<float, 5, 2> CDt = Eigen::Matrix<float, 5, 2>::Zero();
  bool normals_everywhere = image.hasNormal(i);
  bool horizontal = false, vertical = false;
  const Eigen::Matrix<float, 5, 1> centre = cuesAt(image, i);
  for (int k = 0; k < 4; ++k) {
    const int j = neighbours[k];
    if (j < 0 || !image.hasPoint(j)) continue;
    if (!onOneSurface(image.range[i], image.range[j], max_jump_ratio)) continue;
    const Eigen::Vector2f df =
        offsetFrom<float>(image.projection, image.subpixel[j], image.subpixel[i]);
    DDt += df * df.transpose();
    CDt += (cuesAt(image, j) - centre) * df.transpose();
    normals_everywhere = normals_everywhere && image.hasNormal(j);
    (k < 2 ? horizontal : vertical) = true;
  }
  if (!horizontal || !vertical) return false;
  const float det = DDt.determinant();
  if (!(det > 1e-3f)) return false;
  *gradient = CDt * DDt.inverse();
  if (!normals_everywhere) gradient->bottomRows<3>().setZero();
  return true;
}

/// The kernel's weight of a pixel with weighted squared error chi2 (IRLS).
float robustWeight(bool cauchy, float width, float chi2) {
  const float width2 = width * width;
  if (cauchy) return 1.0f / (1.0f + chi2 / width2);
  return chi2 <= width2 ? 1.0f : width / std::sqrt(chi2);  // Huber
}

/// The adjoint that carries a perturbation applied on the right of T to one applied on its left,
/// ordered (translation, rotation).
Matrix6d adjoint(const Eigen::Isometry3d& T) {
  Matrix6d ad = Matrix6d::Zero();
  ad.topLeftCorner<3, 3>() = T.linear();
  ad.topRightCorner<3, 3>() = skew<double>(T.translation()) * T.linear();
  ad.bottomRightCorner<3, 3>() = T.linear();
  return ad;
}

/// One level's scratch: where every model point lands in the measured image.
struct Rendering {
  std::vector<float> depth;            ///< per measured pixel, the nearest rendered range
  std::vector<int> owner;              ///< per measured pixel, the model pixel rendered there
  std::vector<int> touched;            ///< measured pixels written this iteration
  std::vector<Eigen::Vector3f> moved;  ///< per model pixel, its point moved by X
  std::vector<Eigen::Vector2f> at;     ///< per model pixel, its continuous (u, v)
};

/// Renders the model's points of `pixels` moved by X into the measured image's pixels through a
/// depth buffer.
void render(const MultiCueImage& model, const std::vector<int>& pixels, const Eigen::Isometry3d& X,
            const SphericalProjectionParams& measured, Rendering& out) {
  out.depth.assign(measured.size(), std::numeric_limits<float>::infinity());
  out.owner.assign(measured.size(), -1);
  out.touched.clear();
  out.moved.resize(model.projection.size());
  out.at.resize(model.projection.size());
  const Eigen::Matrix3f R = X.linear().cast<float>();
  const Eigen::Vector3f t = X.translation().cast<float>();
  for (const int j : pixels) {
    const Eigen::Vector3f q = R * model.point[j] + t;
    float u = 0.0f, v = 0.0f, r = 0.0f;
    if (!measured.project(q, &u, &v, &r)) continue;
    const int i = static_cast<int>(v) * measured.cols + static_cast<int>(u);
    if (r >= out.depth[i]) continue;
    if (out.owner[i] < 0) out.touched.push_back(i);
    out.depth[i] = r;
    out.owner[i] = j;
    out.moved[j] = q;
    out.at[j] = Eigen::Vector2f(u, v);
  }
}

/// What the residual reads of one measured pixel, in one place (72 bytes): the Gauss-Newton
/// loop visits tens of thousands of pixels per iteration and was bound by fetching them from six
/// image arrays.
struct MeasuredPixel {
  Eigen::Matrix<float, 5, 2> gradient;  ///< d cues / d (u, v)
  Eigen::Matrix<float, 5, 1> cues;      ///< range, intensity, normal x y z
  Eigen::Vector2f subpixel;             ///< the return's (u, v)
  bool has_normal = false;
};

MeasuredPixel measuredPixel(const MultiCueImage& image, int i,
                            const Eigen::Matrix<float, 5, 2>& gradient) {
  MeasuredPixel m;
  m.gradient = gradient;
  m.cues = cuesAt(image, i);
  m.subpixel = image.subpixel[i];
  m.has_normal = image.hasNormal(i);
  return m;
}

template <typename Scalar>
struct PixelResidual {
  Eigen::Matrix<Scalar, 5, 1> error = Eigen::Matrix<Scalar, 5, 1>::Zero();
  Eigen::Matrix<Scalar, 5, 6> jacobian = Eigen::Matrix<Scalar, 5, 6>::Zero();
  bool intensity_valid = false;
  bool normal_valid = false;
};

/// The residual of a model point already moved to q (its normal rotated, zero when it has none)
/// and projected to the continuous pixel `at`, against a measured pixel; double for the Jacobian
/// test, float in the Gauss-Newton loop. use_intensity: both images carry intensity and its
/// weight is not zero.
template <typename Scalar>
void residualAt(const Eigen::Matrix<Scalar, 3, 1>& q, const Eigen::Matrix<Scalar, 2, 1>& at,
                const Eigen::Matrix<Scalar, 3, 1>& rotated_normal, float model_intensity,
                const SphericalProjectionParams& projection, const MeasuredPixel& measured,
                bool use_intensity, bool use_normal, PixelResidual<Scalar>* r) {
  const Scalar range = q.norm();
  const Eigen::Matrix<Scalar, 2, 1> offset = offsetFrom<Scalar>(projection, at, measured.subpixel);
  const Eigen::Matrix<Scalar, 5, 2> G = measured.gradient.cast<Scalar>();
  const Eigen::Matrix<Scalar, 5, 1> measured_cues = measured.cues.cast<Scalar>() + G * offset;

  // q <- exp(delta) q moves q by (I, -[q]x) delta; the projection turns that into a pixel shift.
  const Eigen::Matrix<Scalar, 2, 3> dpixel_dq = projection.projectionJacobian<Scalar>(q);
  // Row a of the rotation block: -a' [q]x = (q x a)'.
  Eigen::Matrix<Scalar, 2, 6> dpixel;
  dpixel.template leftCols<3>() = dpixel_dq;
  dpixel.row(0).template tail<3>() = q.cross(dpixel_dq.row(0).transpose()).transpose();
  dpixel.row(1).template tail<3>() = q.cross(dpixel_dq.row(1).transpose()).transpose();

  // The range does not change when q turns about the sensor: its rotation block is zero.
  r->error(0) = range - measured_cues(0);
  r->jacobian.row(0) << q.transpose() / range, Scalar(0), Scalar(0), Scalar(0);
  r->jacobian.row(0) -= G.row(0) * dpixel;
  r->intensity_valid = use_intensity;
  if (r->intensity_valid) {
    r->error(1) = Scalar(model_intensity) - measured_cues(1);
    r->jacobian.row(1) = -G.row(1) * dpixel;
  }
  r->normal_valid = use_normal && measured.has_normal && rotated_normal.squaredNorm() > Scalar(0);
  if (r->normal_valid) {
    r->error.template tail<3>() = rotated_normal - measured_cues.template tail<3>();
    r->jacobian.template bottomLeftCorner<3, 3>().setZero();
    r->jacobian.template bottomRightCorner<3, 3>() = -skew<Scalar>(rotated_normal);
    r->jacobian.template bottomRows<3>() -= G.template bottomRows<3>() * dpixel;
  }
}

/// The measured image's cue gradients, computed the first time a pixel is asked for: the
/// rendered model reaches about half of the image's pixels.
class LazyGradients {
 public:
  LazyGradients(const MultiCueImage& image, double max_range_jump_ratio)
      : image_(image),
        max_range_jump_ratio_(max_range_jump_ratio),
        pixel_(image.projection.size()),
        state_(image.projection.size(), kUnknown) {}

  /// Pixel i with its gradient, or nullptr where the image has no return or no gradient.
  const MeasuredPixel* at(int i) {
    if (state_[i] == kUnknown) {
      Eigen::Matrix<float, 5, 2> gradient;
      const bool ok = image_.hasPoint(i) && gradientAt(image_, i, max_range_jump_ratio_, &gradient);
      if (ok) pixel_[i] = measuredPixel(image_, i, gradient);
      state_[i] = ok ? kValid : kInvalid;
    }
    return state_[i] == kValid ? &pixel_[i] : nullptr;
  }

 private:
  enum : uint8_t { kUnknown, kValid, kInvalid };
  const MultiCueImage& image_;
  double max_range_jump_ratio_;
  std::vector<MeasuredPixel> pixel_;
  std::vector<uint8_t> state_;
};

/// The model pixels with a return; with stride 2 only those with an even row + column (a
/// checkerboard: every row and column keeps half of its returns).
std::vector<int> modelPixels(const MultiCueImage& model, int stride) {
  std::vector<int> pixels;
  pixels.reserve(model.projection.size() / std::max(1, stride));
  for (int row = 0; row < model.rows(); ++row) {
    for (int col = 0; col < model.cols(); ++col) {
      const int i = model.index(row, col);
      if (model.hasPoint(i) && (stride <= 1 || (row + col) % stride == 0)) pixels.push_back(i);
    }
  }
  return pixels;
}

struct NormalEquations {
  Matrix6d H = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  double chi2 = 0.0;
  int inliers = 0;
};

/// What the Gauss-Newton loop needs of the parameters, in the types it uses per pixel.
struct PixelWeighting {
  Eigen::Matrix<float, 5, 1> weights;  ///< range, intensity, normal x3 (zero: cue off)
  bool cauchy = false;
  float kernel_width = 0.0f;
  float range_gate = 0.0f;
};

/// Accumulates J' W J, J' W e and chi2 over rendered pixels [begin, end): float per pixel (the
/// points are float), summed into double in blocks so that tens of thousands of pixels lose no
/// precision.
NormalEquations lineariseRange(const MultiCueImage& model, const Eigen::Isometry3d& X,
                               const MultiCueImage& measured, LazyGradients& gradients,
                               const Rendering& rendering, const PixelWeighting& weighting,
                               size_t begin, size_t end) {
  const Eigen::Matrix<float, 5, 1>& weights = weighting.weights;
  const bool cauchy = weighting.cauchy;
  const float kernel_width = weighting.kernel_width, range_gate = weighting.range_gate;
  NormalEquations eq;
  const Eigen::Matrix3f R = X.linear().cast<float>();
  Eigen::Matrix<float, 6, 6> H_block = Eigen::Matrix<float, 6, 6>::Zero();
  Eigen::Matrix<float, 6, 1> b_block = Eigen::Matrix<float, 6, 1>::Zero();
  PixelResidual<float> r;
  int in_block = 0;
  for (size_t k = begin; k < end; ++k) {
    const int pixel = rendering.touched[k];
    const int j = rendering.owner[pixel];
    const MeasuredPixel* m = gradients.at(pixel);
    if (!m) continue;
    residualAt<float>(rendering.moved[j], rendering.at[j], R * model.normal[j], model.intensity[j],
                      measured.projection, *m, weights(1) > 0.0f, weights(2) > 0.0f, &r);
    if (!(std::abs(r.error(0)) <= range_gate)) continue;
    Eigen::Matrix<float, 5, 1> w = weights;
    if (!r.intensity_valid) w(1) = 0.0f;
    if (!r.normal_valid) w.tail<3>().setZero();
    const float chi2 = r.error.dot(w.cwiseProduct(r.error));
    w *= robustWeight(cauchy, kernel_width, chi2);
    const Eigen::Matrix<float, 6, 5> JtW = r.jacobian.transpose() * w.asDiagonal();
    H_block.noalias() += JtW * r.jacobian;
    b_block.noalias() += JtW * r.error;
    eq.chi2 += chi2;
    ++eq.inliers;
    if (++in_block == 256) {
      eq.H += H_block.cast<double>();
      eq.b += b_block.cast<double>();
      H_block.setZero();
      b_block.setZero();
      in_block = 0;
    }
  }
  eq.H += H_block.cast<double>();
  eq.b += b_block.cast<double>();
  // J' W J summed in float is symmetric only up to rounding.
  eq.H = 0.5 * (eq.H + eq.H.transpose()).eval();
  return eq;
}

/// Rendered pixels per task: the chunks are fixed, and summed in their order, so the result
/// does not depend on the number of threads or on the scheduling.
constexpr size_t kPixelsPerChunk = 2048;

/// lineariseRange over every rendered pixel, in parallel chunks. Each pixel appears once in
/// `touched`, so the chunks' on-demand gradients never touch the same entry.
NormalEquations linearise(tbb::task_arena& arena, const MultiCueImage& model,
                          const Eigen::Isometry3d& X, const MultiCueImage& measured,
                          LazyGradients& gradients, const Rendering& rendering,
                          const PixelWeighting& weighting) {
  const size_t n = rendering.touched.size();
  std::vector<NormalEquations> partial((n + kPixelsPerChunk - 1) / kPixelsPerChunk);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, partial.size(), 1),
                      [&](const tbb::blocked_range<size_t>& chunks) {
                        for (size_t c = chunks.begin(); c < chunks.end(); ++c) {
                          partial[c] = lineariseRange(model, X, measured, gradients, rendering,
                                                      weighting, c * kPixelsPerChunk,
                                                      std::min(n, (c + 1) * kPixelsPerChunk));
                        }
                      });
  });
  NormalEquations eq;
  for (const NormalEquations& p : partial) {
    eq.H += p.H;
    eq.b += p.b;
    eq.chi2 += p.chi2;
    eq.inliers += p.inliers;
  }
  return eq;
}

/// The gradients of every rendered pixel, in parallel (each pixel once).
void computeGradientsOf(tbb::task_arena& arena, const Rendering& rendering,
                        LazyGradients& gradients) {
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rendering.touched.size(), kPixelsPerChunk),
                      [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t k = r.begin(); k < r.end(); ++k)
                          gradients.at(rendering.touched[k]);
                      });
  });
}

}  // namespace

std::string MultiCueParams::validate() const {
  std::ostringstream why;
  if (pyramid_levels < 1)
    why << "pyramid_levels must be >= 1";
  else if (model_stride < 1)
    why << "model_stride must be >= 1";
  else if (max_iterations_per_level < 1)
    why << "max_iterations_per_level must be >= 1";
  else if (!(range_weight >= 0.0) || !(intensity_weight >= 0.0) || !(normal_weight >= 0.0))
    why << "the cue weights must be >= 0";
  else if (range_weight + intensity_weight + normal_weight <= 0.0)
    why << "at least one cue weight must be positive";
  else if (kernel != "huber" && kernel != "cauchy")
    why << "kernel must be huber or cauchy, not '" << kernel << "'";
  else if (!(kernel_width > 0.0))
    why << "kernel_width must be > 0";
  else if (!(range_gate > 0.0))
    why << "range_gate must be > 0";
  else if (!(translation_epsilon > 0.0) || !(rotation_epsilon > 0.0))
    why << "the convergence thresholds must be > 0";
  return why.str();
}

CueGradients computeCueGradients(const MultiCueImage& measured,
                                 const SurfaceContinuityParams& continuity) {
  CueGradients g;
  const int n = measured.projection.size();
  g.gradient.assign(n, Eigen::Matrix<float, 5, 2>::Zero());
  g.valid.assign(n, 0);
  for (int i = 0; i < n; ++i) {
    if (measured.hasPoint(i))
      g.valid[i] = gradientAt(measured, i, continuity.max_range_jump_ratio, &g.gradient[i]);
  }
  return g;
}

bool cueResidual(const Eigen::Vector3f& model_point, const Eigen::Vector3f& model_normal,
                 float model_intensity, const Eigen::Isometry3d& X, const MultiCueImage& measured,
                 const CueGradients& gradients, int pixel, CueResidual* out) {
  if (pixel < 0 || pixel >= measured.projection.size()) return false;
  const Eigen::Vector3d q = X * model_point.cast<double>();
  if (q.head<2>().squaredNorm() <= 0.0) return false;
  const Eigen::Vector3d rotated_normal = X.linear() * model_normal.cast<double>();
  if (!measured.hasPoint(pixel) || !gradients.valid[pixel]) return false;
  PixelResidual<double> r;
  residualAt<double>(q, pixelOf(measured.projection, q), rotated_normal, model_intensity,
                     measured.projection, measuredPixel(measured, pixel, gradients.gradient[pixel]),
                     measured.has_intensity, true, &r);
  out->error = r.error;
  out->jacobian = r.jacobian;
  out->intensity_valid = r.intensity_valid;
  out->normal_valid = r.normal_valid;
  return true;
}

MultiCueRegistration::MultiCueRegistration(const MultiCueParams& params,
                                           const SurfaceContinuityParams& continuity)
    : params_(params), continuity_(continuity) {}

MultiCueResult MultiCueRegistration::align(const MultiCuePyramid& model,
                                           const MultiCuePyramid& current,
                                           const Eigen::Isometry3d& guess) const {
  const auto start = Clock::now();
  MultiCueResult result;
  result.transform = guess;
  if (const std::string why = params_.validate(); !why.empty()) {
    result.message = "multi-cue parameters: " + why;
    return result;
  }
  const int levels =
      std::min<int>({params_.pyramid_levels, int(model.levels.size()), int(current.levels.size())});
  if (levels < 1) {
    result.message = "empty pyramid";
    return result;
  }
  const bool use_intensity =
      model.has_intensity() && current.has_intensity() && params_.intensity_weight > 0.0;
  result.intensity_used = use_intensity;
  PixelWeighting weighting;
  weighting.weights << params_.range_weight, use_intensity ? params_.intensity_weight : 0.0,
      params_.normal_weight, params_.normal_weight, params_.normal_weight;
  weighting.cauchy = params_.kernel == "cauchy";
  weighting.kernel_width = params_.kernel_width;
  weighting.range_gate = params_.range_gate;
  tbb::task_arena arena(params_.num_threads > 0 ? params_.num_threads : tbb::task_arena::automatic);

  Eigen::Isometry3d X = guess.inverse();  // model -> current sensor frame
  Rendering rendering;
  NormalEquations last;
  bool finest_converged = false;
  for (int level = levels - 1; level >= 0; --level) {
    const MultiCueImage& model_image = model.levels[level];
    const MultiCueImage& measured = current.levels[level];
    if (model_image.rows() != measured.rows() || model_image.cols() != measured.cols()) {
      result.message = "the model and the current scan come from different projections";
      result.time_ms = msSince(start);
      return result;
    }
    const std::vector<int> model_pixels = modelPixels(model_image, params_.model_stride);
    LazyGradients gradients(measured, continuity_.max_range_jump_ratio);
    bool level_converged = false;
    for (int iteration = 0; iteration < params_.max_iterations_per_level; ++iteration) {
      render(model_image, model_pixels, X, measured.projection, rendering);
      if (iteration == 0) {  // later iterations reach few new pixels
        const auto gradients_start = Clock::now();
        computeGradientsOf(arena, rendering, gradients);
        result.gradients_ms += msSince(gradients_start);
      }
      const NormalEquations eq =
          linearise(arena, model_image, X, measured, gradients, rendering, weighting);
      ++result.iterations;
      last = eq;
      if (eq.inliers < 6) break;
      const Eigen::LDLT<Matrix6d> solver(eq.H);
      if (solver.info() != Eigen::Success) break;
      const Vector6d delta = -solver.solve(eq.b);
      if (!delta.allFinite()) break;
      X = applyIncrement(delta, X);
      // A coarse level only has to bring the next one into its basin: its pixels are 2^level
      // times larger, and so are its thresholds.
      const double scale = double(1 << level);
      if (delta.head<3>().norm() < scale * params_.translation_epsilon &&
          delta.tail<3>().norm() < scale * params_.rotation_epsilon) {
        level_converged = true;
        break;
      }
    }
    if (level == 0) finest_converged = level_converged;
  }

  result.transform = X.inverse();
  result.inliers = last.inliers;
  result.chi2 = last.chi2;
  // The last normal equations were built for X <- exp(delta) X, i.e. transform <- transform *
  // exp(-delta); carry them to a perturbation on the left of transform.
  const Matrix6d ad_inverse = adjoint(result.transform).inverse();
  result.information = ad_inverse.transpose() * last.H * ad_inverse;
  result.converged = finest_converged && last.inliers >= params_.min_inliers;
  if (!result.converged) {
    std::ostringstream why;
    if (last.inliers < params_.min_inliers)
      why << last.inliers << " inlier pixels, below min_inliers " << params_.min_inliers;
    else
      why << "no convergence within " << params_.max_iterations_per_level
          << " iterations at the finest level";
    result.message = why.str();
  }
  result.time_ms = msSince(start);
  return result;
}

}  // namespace osm_graph_slam
