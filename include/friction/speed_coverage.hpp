// Whether a validation record moves where its model was identified.
//
// A model's speed-dependent terms -- the Stribeck curve and viscous term of LuGre, GMS and the
// static curve, and the extension pieces stribeck, viscous and frictional-lag -- are fitted on the
// speeds the estimation record holds.  Above the largest of them the record says nothing about
// them: a Stribeck curve whose velocity lies above the record's speeds is pinned by its fall at low
// speed only, and curves that fit the estimation record equally well part by several noise sigmas
// at twice its speeds (README, "The discovery study": on study records whose validation record
// moved 3-5 times faster than the estimation record, the told Stribeck fit matched the true
// system on the estimation record and validated at 2.7-12 times the floor).  A validation error
// measured there measures the extrapolation, not the fit, so `identify`, `compare` and `validate`
// say when a record asks for it.
//
// The speeds are v(t_k) by the local polynomial of sample_derivatives.hpp, the estimate the
// models' speed-dependent terms are fed, on the displacement as measured.  The largest speed of
// the estimation record is its maximum: a validation sample above it is outside what the fit saw,
// whatever the noise of the estimate (the estimation record's own noise already widened its
// maximum).  The warning asks for more than 1 % of the validation samples there, so that a few
// noisy peaks do not raise it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "friction/record.hpp"
#include "friction/sample_derivatives.hpp"

namespace friction {

/// |v(t_k)| of a record (sample_derivatives.hpp); empty for fewer than 16 samples.
inline std::vector<double> sample_speeds(const Record& r) {
  if (r.size() < 16) return {};
  SampleDerivatives d = sample_derivatives(std::span<const double>(r.time),
                                           std::span<const double>(r.measured()));
  for (double& v : d.velocity) v = std::abs(v);
  return std::move(d.velocity);
}

/// The largest |v(t_k)| of a record [m/s] (0 for fewer than 16 samples).
inline double largest_speed(const Record& r) {
  const std::vector<double> s = sample_speeds(r);
  return s.empty() ? 0.0 : *std::max_element(s.begin(), s.end());
}

/// How much of a validation record moves faster than the estimation record ever did.
struct SpeedCoverage {
  double estimation_largest = 0;  ///< [m/s]
  double validation_largest = 0;  ///< [m/s]
  std::size_t faster = 0;         ///< validation samples with |v| > estimation_largest
  std::size_t samples = 0;        ///< validation samples judged
  double fraction() const { return samples ? double(faster) / double(samples) : 0.0; }
};

inline SpeedCoverage speed_coverage(double estimation_largest, const Record& validation) {
  SpeedCoverage c;
  c.estimation_largest = estimation_largest;
  const std::vector<double> s = sample_speeds(validation);
  c.samples = s.size();
  for (double v : s) {
    c.validation_largest = std::max(c.validation_largest, v);
    c.faster += v > estimation_largest;
  }
  return c;
}

/// The terms of a model, given as its JSON (AnyModel::to_json), whose force depends on the speed.
inline std::vector<std::string> speed_dependent_terms(const nlohmann::json& model) {
  std::vector<std::string> terms;
  const std::string type = model.value("type", std::string());
  if (type == "lugre" || type == "gms" || type == "static")
    terms.push_back(type + "'s Stribeck curve and viscous term");
  if (model.contains("extensions") && model["extensions"].is_object())
    for (const char* piece : {"stribeck", "viscous", "frictional-lag"})
      if (model["extensions"].contains(piece)) terms.push_back(piece);
  return terms;
}

/// The warning of the header comment, or nothing: more than 1 % of the validation samples faster
/// than the estimation record's largest speed, and a model with speed-dependent terms.
inline std::optional<std::string> speed_extrapolation_warning(
    const SpeedCoverage& c, const std::vector<std::string>& terms) {
  if (terms.empty() || c.samples == 0 || !(c.estimation_largest > 0) || c.fraction() <= 0.01)
    return std::nullopt;
  std::string names;
  for (std::size_t i = 0; i < terms.size(); ++i)
    names += (i == 0 ? "" : i + 1 == terms.size() ? " and " : ", ") + terms[i];
  char text[160];
  std::snprintf(text, sizeof text, "on %.3g %% of its samples (up to %.3g m/s, against %.3g m/s)",
                100.0 * c.fraction(), c.validation_largest, c.estimation_largest);
  return "the validation record moves faster than the estimation record ever did " +
         std::string(text) + ": the model's speed-dependent terms (" + names +
         ") are extrapolated there, and the validation error there measures the extrapolation";
}

}  // namespace friction
