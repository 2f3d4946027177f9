// Models of any type, with their extensions, as JSON documents: what the CLI saves and loads and
// what a controller reads at start-up.
//
// A model document is
//   {
//     "type": "maxwell-slip" | "dnlrx" | "lugre" | "gms" | "static",
//     "parameters": { ... per type, SI units, names as in the paper ... },
//     "units": { name: unit, ... },                    (written for people; ignored on reading)
//     "extensions": { "<effect>": { <parameter>: value, ... }, ... }   (methods.md section 7)
//   }
// and may stand alone or as the member "model" of a larger document (the output of `identify`).
// Parameters per type:
//   maxwell-slip  stiffness[] [N/m], threshold[] [m]                                  (eqs. 4-5)
//   dnlrx         threshold[] [m], spring_filter[][] [N/m] (M rows of n+1 taps),
//                 input_filter[] [N/m] (nx+1 taps; may be empty)                 (methods.md 4)
//   lugre         stiffness sigma0 [N/m], micro_damping sigma1 [N s/m], viscous sigma2 [N s/m],
//                 coulomb Fc [N], static Fs [N], stribeck_velocity vs [m/s],
//                 stribeck_exponent mu, shape "rational" (eq. 3) | "exponential"    (eqs. 1-3)
//   gms           stiffness[] [N/m], share[] alpha_i, coulomb, static, stribeck_velocity,
//                 stribeck_exponent, attraction C [N/s], viscous sigma2 [N s/m]   (methods.md 5)
//   static        coulomb, static, stribeck_velocity, stribeck_exponent, viscous
//
// `AnyModel` evaluates such a model in double, sample by sample (`step`) or over a record.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <variant>
#include <vector>

#include "friction/dnlrx.hpp"
#include "friction/extensions.hpp"
#include "friction/gms.hpp"
#include "friction/lugre.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/record.hpp"
#include "friction/static_friction.hpp"

namespace friction {

using Json = nlohmann::json;

/// The model types of the CLI contract, in the order of `AnyModel::Variant`.
inline constexpr const char* kModelTypes[] = {"maxwell-slip", "dnlrx", "lugre", "gms", "static"};

/// A model of any type with its extensions, in double precision.
class AnyModel {
 public:
  using Variant =
      std::variant<Extended<MaxwellSlip<double>>, Extended<Dnlrx<double>>, Extended<LuGre<double>>,
                   Extended<Gms<double>>, Extended<StaticFriction<double>>>;
  using Scalar = double;

  explicit AnyModel(Variant model) : model_(std::move(model)) {}

  /// Reads a model document (bare, or with the model under "model").  `source` names the file in
  /// messages.  Throws DataError for a malformed document, InvalidParameter for bad values.
  static AnyModel from_json(const Json& document, const std::string& source = "");
  /// Reads a model document from a file (DataError with line and column on a JSON syntax error).
  static AnyModel load(const std::string& path);

  Json to_json() const;
  std::string type() const;
  /// Number of free parameters (base and extensions).
  std::size_t parameter_count() const;
  const ExtensionParameters<double>& extensions() const;
  /// The same base with other extensions.
  AnyModel with_extensions(const ExtensionParameters<double>& extensions) const;

  const Variant& variant() const noexcept { return model_; }
  Variant& variant() noexcept { return model_; }

  void reset();
  double step(const Motion<double>& motion) noexcept;
  /// Free-run simulation over the record from the virgin state (the record's normal force feeds a
  /// normal-load extension).
  std::vector<double> simulate(const Record& record);

 private:
  Variant model_;
};

/// Parses a --model TYPE name; throws InvalidParameter listing the accepted names.
std::string check_model_type(const std::string& type);

/// A reference system of each type with physically sensible parameters (sliding level about
/// 1.5 N, presliding travel of some micrometres): the default of `generate`.  `rate` [Hz] sets
/// the DNLRX input filter, whose taps act on increments per sample.
AnyModel reference_model(const std::string& type, double rate);

/// Parses an effect specification "NAME=VALUE[,param=value...]" (VALUE sets the effect's main
/// parameter, methods.md section 7) into `extensions`.  Throws InvalidParameter.
void parse_effect(const std::string& spec, ExtensionParameters<double>& extensions);

/// Builds the extension pieces from their JSON object ({"viscous": {"viscous": 2.0}, ...}).
ExtensionParameters<double> extensions_from_json(const Json& j, const std::string& source);
Json extensions_to_json(const ExtensionParameters<double>& extensions);

}  // namespace friction
