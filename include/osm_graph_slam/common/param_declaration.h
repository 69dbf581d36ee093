#pragma once
// Parameters declared once. A params struct lists its keys in one member template,
//
//   template <class V> void visit(V& v) {
//     v("gnss_prior_std", gnss_prior_std, "[m] GNSS position prior on every keyframe with a fix");
//     v("loop_kernel", loop_kernel, "robust kernel of loop edges", kKernelChoices);
//   }
//
// (key, field, one-line doc; a string field may name its allowed values), and the field's
// initialiser stays its only default. Reading (readDeclaredParams below), listing the keys and
// their defaults (config_consistency_test, the advanced YAML files) all follow from that one
// list. No dependency beyond ParamReader: this header is included by the params headers.
#include <string>

#include "osm_graph_slam/common/param_reader.h"

namespace osm_graph_slam {

/// The robust kernels an edge's kernel name may give (kernelNamed()).
inline constexpr const char* kKernelChoices = "none | huber | cauchy";

/// Whether `value` is one of `choices` ("a | b | c").
inline bool isParamChoice(const std::string& value, const std::string& choices) {
  size_t start = 0;
  while (start <= choices.size()) {
    size_t end = choices.find(" | ", start);
    if (end == std::string::npos) end = choices.size();
    if (choices.compare(start, end - start, value) == 0 && end - start == value.size()) return true;
    start = end + 3;
  }
  return false;
}

/// Reads each declared key from a ParamReader into its field; a missing key leaves the field as it
/// is. A string outside its choices is an error and keeps the field's value (a misspelt kernel
/// name would otherwise silently become no kernel at all).
class ParamReadVisitor {
 public:
  ParamReadVisitor(const ParamReader& reader, std::string* error) : r_(reader), error_(error) {}

  template <class T>
  void operator()(const char* key, T& field, const char* /*doc*/) {
    r_.param(key, field);
  }
  void operator()(const char* key, std::string& field, const char* /*doc*/, const char* choices) {
    std::string value = field;
    r_.param(key, value);
    if (isParamChoice(value, choices)) {
      field = value;
      return;
    }
    fail("unknown " + std::string(key) + " '" + value + "' (" + choices + ")");
  }
  void fail(const std::string& message) {
    ok_ = false;
    if (error_) *error_ = message;
  }
  bool ok() const { return ok_; }

 private:
  const ParamReader& r_;
  std::string* error_;
  bool ok_ = true;
};

/// Reads every key `params.visit()` declares. Returns false with a reason for a value outside its
/// choices; the other keys are still read.
template <class Params>
bool readDeclaredParams(const ParamReader& reader, Params& params, std::string* error) {
  ParamReadVisitor visitor(reader, error);
  params.visit(visitor);
  return visitor.ok();
}

}  // namespace osm_graph_slam
