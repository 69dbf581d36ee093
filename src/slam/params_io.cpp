#include "osm_graph_slam/slam/params_io.h"

namespace osm_graph_slam {

bool readParams(const ParamReader& r, OdometryEdgeParams& p, std::string* error) {
  ParamReadVisitor v(r, error);
  p.visit(v);
  // An out-of-range value is an error and keeps the code default.
  InformationParams& i = p.information;
  if (!(i.prediction_error_scale >= 0.0)) {
    v.fail("odometry_prediction_error_scale must be >= 0");
    i.prediction_error_scale = InformationParams{}.prediction_error_scale;
  }
  if (!(i.hessian_weight >= 0.0)) {
    v.fail("odometry_hessian_weight must be >= 0");
    i.hessian_weight = InformationParams{}.hessian_weight;
  }
  if (!(i.lateral_std_ratio > 0.0)) {
    v.fail("odometry_lateral_std_ratio must be > 0");
    i.lateral_std_ratio = InformationParams{}.lateral_std_ratio;
  }
  if (p.odometry_scale_window > 0.0 &&
      !(p.odometry_scale_std > 0.0 && p.odometry_scale_walk_std > 0.0)) {
    v.fail("odometry_scale_std and odometry_scale_walk_std must be > 0");
    p.odometry_scale_window = 0.0;
  }
  if (!(p.odometry_scale_window >= 0.0)) {
    v.fail("odometry_scale_window must be >= 0");
    p.odometry_scale_window = 0.0;
  }
  return v.ok();
}

bool readParams(const ParamReader& r, OptimizationScheduleParams& p, std::string* error) {
  bool ok = readDeclaredParams(r, p, error);
  if (!readParams(PrefixedParamReader(r, "graph_optimizer"), p.optimizer, error)) ok = false;
  return ok;
}

bool readParams(const ParamReader& r, GraphBackendParams& p, std::string* error) {
  bool ok = true;
  std::string mode = toString(p.mode);
  r.param("mode", mode);
  if (!parseOsmMode(mode, &p.mode)) {
    ok = false;
    if (error) *error = "unknown mode '" + mode + "' (prior | rigid | non_rigid)";
  }
  if (!readDeclaredParams(r, p, error)) ok = false;
  if (!readDeclaredParams(r, p.inputs, error)) ok = false;
  if (!readParams(r, p.odometry, error)) ok = false;
  if (!readDeclaredParams(r, p.gnss, error)) ok = false;
  if (!readDeclaredParams(r, p.floor, error)) ok = false;
  if (!readDeclaredParams(r, p.loops, error)) ok = false;
  if (!readDeclaredParams(r, p.association, error)) ok = false;
  if (!readDeclaredParams(r, p.osm_prior, error)) ok = false;
  if (!readDeclaredParams(r, p.buildings, error)) ok = false;
  readParams(PrefixedParamReader(r, "line_matcher"), p.matcher);
  if (!readParams(r, p.schedule, error)) ok = false;
  if (!readDeclaredParams(r, p.grid, error)) ok = false;
  if (!readDeclaredParams(r, p.cloud_store, error)) ok = false;
  return ok;
}

bool readParams(const ParamReader& r, OptimizerOptions& p, std::string* error) {
  r.param("max_iterations", p.max_iterations);
  r.param("function_tolerance", p.function_tolerance);
  r.param("gradient_tolerance", p.gradient_tolerance);
  r.param("parameter_tolerance", p.parameter_tolerance);
  r.param("num_threads", p.num_threads);
  r.param("initial_trust_region_radius", p.initial_trust_region_radius);
  r.param("analytic_jacobians", p.analytic_jacobians);
  r.param("verbose", p.verbose);
  std::string library = p.sparse_library == SparseLibrary::kSuiteSparse   ? "suite_sparse"
                        : p.sparse_library == SparseLibrary::kEigenSparse ? "eigen_sparse"
                                                                          : "auto";
  r.param("sparse_library", library);
  r.param("auto_eigen_max_free_vertices", p.auto_eigen_max_free_vertices);
  if (library == "auto") {
    p.sparse_library = SparseLibrary::kAuto;
  } else if (library == "suite_sparse") {
    p.sparse_library = SparseLibrary::kSuiteSparse;
  } else if (library == "eigen_sparse") {
    p.sparse_library = SparseLibrary::kEigenSparse;
  } else {
    if (error)
      *error = "unknown sparse_library '" + library + "' (auto | suite_sparse | eigen_sparse)";
    return false;
  }
  return true;
}

}  // namespace osm_graph_slam
