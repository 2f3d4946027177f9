// The identification methods behind one interface: what `identify`, `validate` and `compare` use.
//
//   LG     lugre         identify_lugre (lg.hpp)
//   NLR    maxwell-slip  identify_maxwell_slip (nlr.hpp)
//   DNLRX  dnlrx         identify_dnlrx (dnlrx_identification.hpp)
//
// Validation scores a fixed model on another record the same way for every method
// (methods.md 2, 6): the initial state is estimated from that record (deflections delta_i(0) for
// the slip models, z0 for LuGre; nothing else is re-estimated), then the model runs free on the
// record's displacement and every sample counts in the error.  Models without an estimator for
// their state (GMS, the static curve, with or without pieces) start from rest, and the result
// says so (`initial_state: "zero"`).  Maxwell Slip, DNLRX and LuGre models carrying extension
// pieces have their initial state estimated through the extended model (free_run_extended,
// extension_identification.hpp).
//
// Extensions.  `MethodOptions::extensions` asks for pieces of methods.md section 7: the base is
// identified by its method, then the pieces are estimated on the same record
// (identify_extensions, extension_identification.hpp; every base is refitted jointly with them,
// LuGre and DNLRX after a first fit with the base held).  The returned model carries the pieces,
// its report the refitted figures, and `extensions` the pieces' report.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "friction/extension_identification.hpp"
#include "friction/identification.hpp"
#include "friction/metrics.hpp"
#include "friction/model_io.hpp"
#include "friction/record.hpp"

namespace friction {

/// Paper name of a model type ("LG", "NLR", "DNLRX"), or the type itself for the others.
std::string method_name(const std::string& type);
/// Model type of a paper name or of a type; throws InvalidParameter for unknown names.
std::string method_type(const std::string& name_or_type);

/// The types `identify` can estimate.
inline constexpr const char* kIdentifiableTypes[] = {"lugre", "maxwell-slip", "dnlrx"};

/// Options common to the methods (0 / negative: the method's default).
struct MethodOptions {
  std::size_t max_operators = 0;   ///< NLR and DNLRX: largest M tried by the order selection
  std::size_t operators = 0;       ///< NLR and DNLRX: fit this M only
  long spring_order = -1;          ///< DNLRX: >= 0 fixes the spring-filter order n
  long input_order = -1;           ///< DNLRX: >= 0 fixes the input-filter order nx
  bool global_stage = true;        ///< NLopt global stage where the method has one
  unsigned seed = 1;               ///< seeds of the global stages (results are reproducible)
  unsigned threads = 0;  ///< DNLRX's order selection, the extensions' restart (0: one per core)
  std::vector<Effect> extensions;  ///< pieces of methods.md 7 to identify with the base
  ExtensionFitOptions extension_fit;
  /// Maxwell Slip base: when the force as recorded wants every stiffness negative because an
  /// inertial force m·a dominates it (the regression of the sliding force on sgn v, 1, v, a finds
  /// m > 0 by more than 4 standard errors), fit the base to F - m·a instead of failing, and say so
  /// in a warning.  Set by diagnose and by identification with extensions, whose pieces then
  /// model the inertia; a plain identification fails with the mass in its message.
  bool base_without_dominant_inertia = false;
  /// DNLRX: the report of identify_model("maxwell-slip") on the same record with these options,
  /// whose order selection DNLRX then reuses instead of running it again (DnlrxOptions::
  /// nlr_report; the same result).  `compare` sets it.
  const IdentificationReport* maxwell_slip_report = nullptr;
};

/// An identified model and everything the method reports about it.
struct IdentifiedModel {
  AnyModel model;
  IdentificationReport report;
  Json initial_state;  ///< {"kind": "estimated", "values": [...], "unit": "m"}
  /// The pieces' report (ExtensionIdentification::to_json) when extensions were asked for; null
  /// otherwise.
  Json extensions;
};

/// Identifies a model of `type` on the record (which must carry a force).  Throws
/// InvalidParameter for a type that cannot be identified, NumericalError when no result could be
/// produced.
IdentifiedModel identify_model(const std::string& type, const Record& estimation,
                               const MethodOptions& options = {});

/// A fixed model scored on a record.
struct Validation {
  ErrorMetrics errors;
  std::vector<double> simulated;
  std::string initial_state;  ///< "estimated" or "zero"
  Json initial_state_values;
  double noise_sigma = 0;          ///< estimated white force noise [N]
  double noise_floor_percent = 0;  ///< RSS/SSS % of that noise alone
};

Validation validate_model(const AnyModel& model, const Record& record);

/// JSON of an error summary: rss_sss_percent, rms, max_abs, r_squared, samples.
Json errors_to_json(const ErrorMetrics& e);
/// JSON of a report's parameters (name, unit, value, standard_error, lower95, upper95), selection
/// table, convergence, starts and correlation.
Json report_to_json(const IdentificationReport& report);

}  // namespace friction
