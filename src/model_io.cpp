#include "friction/model_io.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "friction/error.hpp"

namespace friction {

namespace {

// Reading -------------------------------------------------------------------------------------

[[noreturn]] void bad(const std::string& source, const std::string& what) {
  throw DataError(source, 0, 0, what);
}

double number(const Json& j, const char* key, const std::string& where, const std::string& source) {
  if (!j.contains(key)) bad(source, where + ": missing \"" + key + "\"");
  const Json& v = j.at(key);
  if (!v.is_number()) bad(source, where + ": \"" + key + "\" must be a number");
  return v.get<double>();
}

double number_or(const Json& j, const char* key, double fallback, const std::string& where,
                 const std::string& source) {
  return j.contains(key) ? number(j, key, where, source) : fallback;
}

std::vector<double> numbers(const Json& j, const char* key, const std::string& where,
                            const std::string& source, bool allow_empty = false) {
  if (!j.contains(key)) bad(source, where + ": missing \"" + key + "\"");
  const Json& v = j.at(key);
  if (!v.is_array()) bad(source, where + ": \"" + key + "\" must be an array of numbers");
  std::vector<double> out;
  for (const Json& e : v) {
    if (!e.is_number()) bad(source, where + ": \"" + key + "\" must hold numbers only");
    out.push_back(e.get<double>());
  }
  if (out.empty() && !allow_empty) bad(source, where + ": \"" + key + "\" is empty");
  return out;
}

StribeckCurve<double> curve_from(const Json& p, const std::string& where, const std::string& src) {
  StribeckCurve<double> c;
  c.coulomb = number(p, "coulomb", where, src);
  c.static_force = number_or(p, "static", c.coulomb, where, src);
  c.stribeck_velocity = number_or(p, "stribeck_velocity", 1e-3, where, src);
  c.stribeck_exponent = number_or(p, "stribeck_exponent", 2.0, where, src);
  return c;
}

Json curve_to(const StribeckCurve<double>& c) {
  return {{"coulomb", c.coulomb},
          {"static", c.static_force},
          {"stribeck_velocity", c.stribeck_velocity},
          {"stribeck_exponent", c.stribeck_exponent}};
}

bool set_parameter(ExtensionParameters<double>& ext, Effect effect, std::string_view name,
                   double value) {
  bool found = false;
  ext.for_each_parameter([&](Effect e, std::string_view n, double& v) {
    if (e == effect && n == name) {
      v = value;
      found = true;
    }
  });
  return found;
}

template <class Base>
Extended<Base> extend(Base base, const ExtensionParameters<double>& ext) {
  return Extended<Base>(std::move(base), ext);
}

}  // namespace

ExtensionParameters<double> extensions_from_json(const Json& j, const std::string& source) {
  ExtensionParameters<double> ext;
  if (j.is_null()) return ext;
  if (!j.is_object()) bad(source, "model: \"extensions\" must be an object");
  for (const auto& [name, params] : j.items()) {
    if (name == "reference_force") {
      if (!params.is_number()) bad(source, "extensions: \"reference_force\" must be a number");
      ext.reference_force = params.get<double>();
      continue;
    }
    const auto effect = effect_from_name(name);
    if (!effect)
      bad(source, "extensions: unknown effect \"" + name + "\" (known: " + effect_names() + ")");
    if (!params.is_object()) bad(source, "extensions: \"" + name + "\" must be an object");
    ext.enable(*effect);
    for (const auto& [key, value] : params.items()) {
      if (!value.is_number())
        bad(source, "extensions." + name + ": \"" + key + "\" must be a number");
      if (!set_parameter(ext, *effect, key, value.get<double>()))
        bad(source, "extensions." + name + ": unknown parameter \"" + key + "\"");
    }
  }
  ext.validate();
  return ext;
}

Json extensions_to_json(const ExtensionParameters<double>& ext) {
  Json j = Json::object();
  ext.for_each_parameter([&](Effect e, std::string_view name, const double& v) {
    j[std::string(effect_name(e))][std::string(name)] = v;
  });
  if (ext.reference_force != 0.0) j["reference_force"] = ext.reference_force;
  return j;
}

AnyModel AnyModel::from_json(const Json& document, const std::string& source) {
  if (!document.is_object()) bad(source, "a model document must be a JSON object");
  const Json& m = document.contains("model") ? document.at("model") : document;
  if (!m.is_object() || !m.contains("type") || !m.at("type").is_string())
    bad(source, "model: missing \"type\" (one of maxwell-slip, dnlrx, lugre, gms, static)");
  const std::string type = m.at("type").get<std::string>();
  if (!m.contains("parameters") || !m.at("parameters").is_object())
    bad(source, "model: missing \"parameters\" object");
  const Json& p = m.at("parameters");
  const std::string where = "model " + type + " parameters";
  const auto ext = extensions_from_json(m.value("extensions", Json()), source);

  if (type == "maxwell-slip") {
    MaxwellSlipParameters<double> mp{numbers(p, "stiffness", where, source),
                                     numbers(p, "threshold", where, source)};
    return AnyModel(extend(MaxwellSlip<double>(mp), ext));
  }
  if (type == "dnlrx") {
    DnlrxParameters<double> dp;
    dp.threshold = numbers(p, "threshold", where, source);
    if (!p.contains("spring_filter") || !p.at("spring_filter").is_array() ||
        p.at("spring_filter").size() != dp.threshold.size())
      bad(source, where + ": \"spring_filter\" must have one row of taps per threshold");
    std::size_t taps = 0;
    for (const Json& row : p.at("spring_filter")) {
      if (!row.is_array() || row.empty())
        bad(source, where + ": spring_filter rows must be arrays");
      if (taps == 0) taps = row.size();
      if (row.size() != taps) bad(source, where + ": spring_filter rows must be equally long");
      for (const Json& e : row) {
        if (!e.is_number()) bad(source, where + ": spring_filter must hold numbers only");
        dp.spring_filter.push_back(e.get<double>());
      }
    }
    dp.spring_order = taps - 1;
    dp.input_filter = numbers(p, "input_filter", where, source, /*allow_empty=*/true);
    return AnyModel(extend(Dnlrx<double>(dp), ext));
  }
  if (type == "lugre") {
    LuGreParameters<double> lp;
    lp.stiffness = number(p, "stiffness", where, source);
    lp.micro_damping = number(p, "micro_damping", where, source);
    lp.viscous = number(p, "viscous", where, source);
    lp.coulomb = number(p, "coulomb", where, source);
    lp.static_force = number(p, "static", where, source);
    lp.stribeck_velocity = number(p, "stribeck_velocity", where, source);
    lp.stribeck_exponent = number(p, "stribeck_exponent", where, source);
    const std::string shape = p.value("shape", std::string("rational"));
    if (shape == "rational") {
      lp.shape = StribeckShape::Rational;
    } else if (shape == "exponential") {
      lp.shape = StribeckShape::Exponential;
    } else {
      bad(source, where + ": \"shape\" must be \"rational\" or \"exponential\"");
    }
    return AnyModel(extend(LuGre<double>(lp), ext));
  }
  if (type == "gms") {
    GmsParameters<double> gp;
    gp.stiffness = numbers(p, "stiffness", where, source);
    gp.share = numbers(p, "share", where, source);
    gp.curve = curve_from(p, where, source);
    gp.attraction = number(p, "attraction", where, source);
    gp.viscous = number_or(p, "viscous", 0.0, where, source);
    return AnyModel(extend(Gms<double>(gp), ext));
  }
  if (type == "static") {
    StaticFrictionParameters<double> sp;
    sp.curve = curve_from(p, where, source);
    sp.viscous = number_or(p, "viscous", 0.0, where, source);
    return AnyModel(extend(StaticFriction<double>(sp), ext));
  }
  bad(source,
      "model: unknown type \"" + type + "\" (one of maxwell-slip, dnlrx, lugre, gms, static)");
}

AnyModel AnyModel::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DataError(path, 0, 0, "cannot open the model file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  Json j;
  try {
    j = Json::parse(text);
  } catch (const Json::parse_error& e) {
    // Byte offset -> line and column, so the message points at the spot.
    long line = 1, column = 1;
    const std::size_t end = std::min<std::size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    for (std::size_t i = 0; i < end; ++i) {
      if (text[i] == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
    }
    throw DataError(path, line, column, "invalid JSON (a model document was expected)");
  }
  return from_json(j, path);
}

Json AnyModel::to_json() const {
  return std::visit(
      [](const auto& ext) -> Json {
        using Base = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        Json j;
        if constexpr (std::is_same_v<Base, MaxwellSlip<double>>) {
          j["type"] = "maxwell-slip";
          j["parameters"] = {{"stiffness", p.stiffness}, {"threshold", p.threshold}};
          j["units"] = {{"stiffness", "N/m"}, {"threshold", "m"}};
        } else if constexpr (std::is_same_v<Base, Dnlrx<double>>) {
          j["type"] = "dnlrx";
          Json rows = Json::array();
          for (std::size_t i = 0; i < p.size(); ++i) {
            Json row = Json::array();
            for (std::size_t k = 0; k < p.spring_taps(); ++k) row.push_back(p.theta(i, k));
            rows.push_back(row);
          }
          j["parameters"] = {{"threshold", p.threshold},
                             {"spring_filter", rows},
                             {"input_filter", p.input_filter}};
          j["units"] = {{"threshold", "m"}, {"spring_filter", "N/m"}, {"input_filter", "N/m"}};
        } else if constexpr (std::is_same_v<Base, LuGre<double>>) {
          j["type"] = "lugre";
          j["parameters"] = {
              {"stiffness", p.stiffness},
              {"micro_damping", p.micro_damping},
              {"viscous", p.viscous},
              {"coulomb", p.coulomb},
              {"static", p.static_force},
              {"stribeck_velocity", p.stribeck_velocity},
              {"stribeck_exponent", p.stribeck_exponent},
              {"shape", p.shape == StribeckShape::Rational ? "rational" : "exponential"}};
          j["units"] = {{"stiffness", "N/m"},      {"micro_damping", "N s/m"},
                        {"viscous", "N s/m"},      {"coulomb", "N"},
                        {"static", "N"},           {"stribeck_velocity", "m/s"},
                        {"stribeck_exponent", "1"}};
        } else if constexpr (std::is_same_v<Base, Gms<double>>) {
          j["type"] = "gms";
          j["parameters"] = curve_to(p.curve);
          j["parameters"]["stiffness"] = p.stiffness;
          j["parameters"]["share"] = p.share;
          j["parameters"]["attraction"] = p.attraction;
          j["parameters"]["viscous"] = p.viscous;
          j["units"] = {{"stiffness", "N/m"},
                        {"share", "1"},
                        {"coulomb", "N"},
                        {"static", "N"},
                        {"stribeck_velocity", "m/s"},
                        {"stribeck_exponent", "1"},
                        {"attraction", "N/s"},
                        {"viscous", "N s/m"}};
        } else {
          j["type"] = "static";
          j["parameters"] = curve_to(p.curve);
          j["parameters"]["viscous"] = p.viscous;
          j["units"] = {{"coulomb", "N"},
                        {"static", "N"},
                        {"stribeck_velocity", "m/s"},
                        {"stribeck_exponent", "1"},
                        {"viscous", "N s/m"}};
        }
        if (!ext.extensions().empty() || ext.extensions().reference_force != 0.0)
          j["extensions"] = extensions_to_json(ext.extensions());
        return j;
      },
      model_);
}

std::string AnyModel::type() const {
  return kModelTypes[model_.index()];
}

std::size_t AnyModel::parameter_count() const {
  return std::visit(
      [](const auto& ext) -> std::size_t {
        using Base = std::decay_t<decltype(ext.base())>;
        const auto& p = ext.base().parameters();
        std::size_t n = ext.extensions().parameter_count();
        if constexpr (std::is_same_v<Base, MaxwellSlip<double>>) {
          n += 2 * p.size();
        } else if constexpr (std::is_same_v<Base, Dnlrx<double>>) {
          n += p.size() + p.spring_filter.size() + p.input_filter.size();
        } else if constexpr (std::is_same_v<Base, LuGre<double>>) {
          n += LuGreParameters<double>::kSize;
        } else if constexpr (std::is_same_v<Base, Gms<double>>) {
          // Shares sum to one: N - 1 free; plus the curve (4), attraction and viscous.
          n += 2 * p.stiffness.size() - 1 + 6;
        } else {
          n += 5;
        }
        return n;
      },
      model_);
}

const ExtensionParameters<double>& AnyModel::extensions() const {
  return std::visit(
      [](const auto& ext) -> const ExtensionParameters<double>& { return ext.extensions(); },
      model_);
}

AnyModel AnyModel::with_extensions(const ExtensionParameters<double>& extensions) const {
  return std::visit(
      [&](const auto& ext) -> AnyModel { return AnyModel(extend(ext.base(), extensions)); },
      model_);
}

void AnyModel::reset() {
  std::visit([](auto& m) { m.reset(); }, model_);
}

double AnyModel::step(const Motion<double>& motion) noexcept {
  return std::visit([&](auto& m) { return m.step(motion); }, model_);
}

std::vector<double> AnyModel::simulate(const Record& record) {
  std::vector<double> force(record.size());
  std::visit(
      [&](auto& m) {
        m.reset();
        simulate_extended(m, std::span<const double>(record.time),
                          std::span<const double>(record.displacement),
                          std::span<const double>(record.normal), std::span<double>(force), nullptr,
                          std::span<const double>(record.measured_displacement));
      },
      model_);
  return force;
}

std::string check_model_type(const std::string& type) {
  for (const char* t : kModelTypes)
    if (type == t) return type;
  throw InvalidParameter("unknown model type '" + type +
                         "' (expected maxwell-slip, dnlrx, lugre, gms or static)");
}

AnyModel reference_model(const std::string& type, double rate) {
  check_model_type(type);
  FRICTION_CHECK(std::isfinite(rate) && rate > 0, "reference model: rate must be > 0 Hz");
  // Four elements: sliding level 1.5 N, presliding travel up to 20 um, viscous 50 N s/m and a
  // Stribeck peak of 2 N below 1 mm/s where the type has them.
  const std::vector<double> k{1.5e5, 8e4, 4e4, 2e4};
  const std::vector<double> d{2e-6, 5e-6, 10e-6, 20e-6};
  const double fc = 1.5, fs = 2.0, vs = 1e-3, sigma2 = 50.0;
  const ExtensionParameters<double> none;
  if (type == "maxwell-slip") return AnyModel(extend(MaxwellSlip<double>({k, d}), none));
  if (type == "dnlrx") {
    DnlrxParameters<double> p;
    p.threshold = d;
    p.spring_order = 1;
    for (double ki : k) {
      p.spring_filter.push_back(0.8 * ki);
      p.spring_filter.push_back(0.2 * ki);
    }
    // Two equal taps on the increments: a viscous force sigma2 * v, averaged over two samples.
    p.input_filter = {0.5 * sigma2 * rate, 0.5 * sigma2 * rate};
    return AnyModel(extend(Dnlrx<double>(p), none));
  }
  if (type == "lugre") {
    LuGreParameters<double> p;
    p.stiffness = 1e5;
    p.micro_damping = 300.0;
    p.viscous = sigma2;
    p.coulomb = fc;
    p.static_force = fs;
    p.stribeck_velocity = vs;
    p.stribeck_exponent = 2.0;
    return AnyModel(extend(LuGre<double>(p), none));
  }
  StribeckCurve<double> curve{fc, fs, vs, 2.0};
  if (type == "gms") {
    GmsParameters<double> p;
    p.stiffness = k;
    double total = 0;
    for (std::size_t i = 0; i < k.size(); ++i) total += k[i] * d[i];
    for (std::size_t i = 0; i < k.size(); ++i) p.share.push_back(k[i] * d[i] / total);
    p.curve = curve;
    p.attraction = fc / 5e-3;  // slipping elements follow g(v) with a lag of about 5 ms
    p.viscous = sigma2;
    return AnyModel(extend(Gms<double>(p), none));
  }
  StaticFrictionParameters<double> p;
  p.curve = curve;
  p.viscous = sigma2;
  return AnyModel(extend(StaticFriction<double>(p), none));
}

void parse_effect(const std::string& spec, ExtensionParameters<double>& ext) {
  const auto fail = [&](const std::string& why) {
    throw InvalidParameter("--effect '" + spec + "': " + why);
  };
  std::vector<std::string> items;
  std::stringstream ss(spec);
  for (std::string item; std::getline(ss, item, ',');) items.push_back(item);
  if (items.empty()) fail("empty");
  const auto split = [&](const std::string& item) {
    const auto eq = item.find('=');
    if (eq == std::string::npos) fail("expected NAME=VALUE[,param=value...]");
    const std::string key = item.substr(0, eq), text = item.substr(eq + 1);
    std::size_t used = 0;
    double value = 0;
    try {
      value = std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != text.size() || !std::isfinite(value))
      fail("'" + text + "' is not a finite number");
    return std::pair<std::string, double>(key, value);
  };
  const auto [name, value] = split(items.front());
  const auto effect = effect_from_name(name);
  if (!effect) fail("unknown effect '" + name + "' (known: " + effect_names() + ")");
  ext.enable(*effect);
  set_parameter(ext, *effect, effect_info(*effect).main_parameter, value);
  for (std::size_t i = 1; i < items.size(); ++i) {
    const auto [key, v] = split(items[i]);
    if (!set_parameter(ext, *effect, key, v))
      fail("effect '" + name + "' has no parameter '" + key + "'");
  }
  ext.validate();
}

}  // namespace friction
