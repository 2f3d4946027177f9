// The evidence of issue 3, as tests that can fail (ctest label "long"; figures in
// .notes/studies.md).
//
// 1. Round trip with coverage, per method, on data of its own model:
//      NLR   on Maxwell Slip data   (reference_model("maxwell-slip"): M = 4)
//      DNLRX on DNLRX data          (reference_model("dnlrx"): M = 4, n = 1, nx = 1)
//      LG    on LuGre data          (reference_model("lugre"))
//    For each of kSeeds seeds an estimation record and a separate validation record are made from
//    the true model (other excitation, other initial state, other noise), the model order is fixed
//    to the truth so that parameters can be compared, and the method runs through the uniform
//    interface (identify_model / validate_model).  Required:
//      * coverage, PER PARAMETER across the seeds: each true parameter lies inside its reported
//        95 % interval in at least 90 % of the seeds.  A fit that reports no standard error for a
//        parameter (interval = the value, with a warning) counts as a miss for it, never as a skip.
//        With exactly calibrated intervals the count is Binomial(seeds, 0.95), and the 90 % rule
//        fails one parameter by chance with probability 7.5 % at 20 seeds, 4.8 % at 40, 1.2 % at
//        100 (so kSeeds = 40, twice the minimum asked for).  The seeds are
//        fixed, so the result is reproducible, and a failure is reported, not re-seeded away.
//      * validation RSS/SSS within 1.2 times the noise floor for EVERY seed, the floor being
//        RSS/SSS of the noise actually added to the validation record (known exactly here).
// 2. The paper's ranking on a GMS system (presliding with nonlocal memory, Stribeck, viscous
//    friction and frictional lag): the bundled pair data/estimation.csv + data/validation.csv made
//    by data/make-data.sh from reference_model("gms") with fixed seeds.  Every method runs with its
//    default order selection on the estimation record only; the validation error must rank
//    DNLRX < NLR < LG.
// 3. The reciprocating tribometer record (real data, shared, skipped when absent): estimation on
//    the first half, validation on the second, all three methods; they must run and give finite
//    errors.  The table is printed for the notes.
//
// Seeds: FRICTION_STUDY_SEEDS overrides kSeeds (for longer studies; the test's thresholds do not
// change with it).  FRICTION_STUDY_VERBOSE=1 prints every fit: errors, parameters, starts.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "friction/csv.hpp"
#include "friction/methods.hpp"
#include "friction/model_io.hpp"
#include "method_studies_support.hpp"

namespace test_method_studies {
namespace {

// The text with every decimal or exponent number ([-+]digits followed by '.' or 'e') replaced by
// '#', while plain integers (indices such as threshold[3]) stay.  (std::regex here trips a false
// -Wmaybe-uninitialized of GCC 12 at -O2.)
std::string mask_decimals(const std::string& w) {
  std::string out;
  std::size_t i = 0;
  const auto digit = [&](std::size_t k) { return k < w.size() && w[k] >= '0' && w[k] <= '9'; };
  while (i < w.size()) {
    std::size_t j = i;
    if ((w[j] == '-' || w[j] == '+') && digit(j + 1)) ++j;
    if (!digit(j) || (j == i && i > 0 && digit(i - 1))) {
      out += w[i++];
      continue;
    }
    std::size_t k = j;
    while (digit(k)) ++k;
    bool decimal = false;
    if (k < w.size() && w[k] == '.') {
      decimal = true;
      ++k;
      while (digit(k)) ++k;
    }
    if (k < w.size() && w[k] == 'e' &&
        (digit(k + 1) ||
         ((k + 1 < w.size()) && (w[k + 1] == '-' || w[k + 1] == '+') && digit(k + 2)))) {
      decimal = true;
      k += digit(k + 1) ? 1 : 2;
      while (digit(k)) ++k;
    }
    out += decimal ? std::string("#") : w.substr(i, k - i);
    i = k;
  }
  return out;
}

using namespace friction;
using friction::studies::Coverage;
using friction::studies::NoisyRecord;
using friction::studies::UniformSource;

constexpr int kSeeds = 40;
constexpr double kRate = 1000.0;      // Hz
constexpr double kSigma = 0.01;       // N: force noise, 0.7 % of the 1.5 N sliding level
constexpr double kCoverage = 0.90;    // per parameter, across the seeds
constexpr double kFloorFactor = 1.2;  // validation RSS/SSS <= 1.2 x the noise floor

int seeds() {
  if (const char* s = std::getenv("FRICTION_STUDY_SEEDS")) {
    const int n = std::atoi(s);
    if (n > 0) return n;
  }
  return kSeeds;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The estimation experiment: strokes of 0.2 mm (ten times the largest presliding travel of the
// reference systems) at five speeds around their Stribeck velocity (1 mm/s), then nested
// presliding loops from 20 um down: 7517 samples at 1 kHz.  Shorter records were tried and are
// worse for NLR, not better: with 0.12 mm strokes (5275 samples) its fixed-order fit ends in a
// local minimum on most seeds (.notes/studies.md).
Signal estimation_excitation() {
  ExcitationOptions o;
  o.kind = ExcitationKind::Combined;
  o.rate = kRate;
  o.stroke = 0.2e-3;
  o.speeds = {2e-4, 5e-4, 1e-3, 2e-3, 5e-3};
  o.presliding_amplitude = 20e-6;
  o.presliding_frequency = 4.0;
  o.presliding_cycles = 6;
  return make_excitation(o);
}

// The validation experiment: other speeds (inside the estimated range), another presliding
// amplitude and frequency, another stroke.
Signal validation_excitation() {
  ExcitationOptions o;
  o.kind = ExcitationKind::Combined;
  o.rate = kRate;
  o.stroke = 0.15e-3;
  o.speeds = {3e-4, 8e-4, 1.5e-3, 3e-3};
  o.presliding_amplitude = 15e-6;
  o.presliding_frequency = 3.0;
  o.presliding_cycles = 5;
  return make_excitation(o);
}

struct StudyOutcome {
  Coverage coverage;
  std::vector<double> ratio;    // validation RSS/SSS over its noise floor, per seed
  std::vector<double> floor;    // the floor [%], per seed
  std::vector<double> seconds;  // identification wall time, per seed
  std::vector<std::string> warnings;
  int samples_estimation = 0, samples_validation = 0;
};

// Runs the round trip for every seed.  `make` returns the noisy record of the true model for
// (excitation, seed) from a random initial state.
template <class Make>
StudyOutcome run_study(const std::string& type, const studies::Truth& truth,
                       const MethodOptions& options, Make make) {
  StudyOutcome out{Coverage(truth), {}, {}, {}, {}, 0, 0};
  const Signal est_x = estimation_excitation(), val_x = validation_excitation();
  out.samples_estimation = static_cast<int>(est_x.time.size());
  out.samples_validation = static_cast<int>(val_x.time.size());
  const int n = seeds();
  for (int s = 1; s <= n; ++s) {
    const NoisyRecord est = make(est_x, 1000 + s);
    const NoisyRecord val = make(val_x, 2000 + s);
    const auto t0 = std::chrono::steady_clock::now();
    const IdentifiedModel id = identify_model(type, est.record, options);
    out.seconds.push_back(seconds_since(t0));
    out.coverage.add(id.report);
    const Validation v = validate_model(id.model, val.record);
    const double floor = studies::noise_floor_percent(val);
    out.floor.push_back(floor);
    out.ratio.push_back(v.errors.rss_sss_percent / floor);
    for (const auto& w : id.report.warnings) out.warnings.push_back(w);
    if (std::getenv("FRICTION_STUDY_VERBOSE")) {
      std::cout << type << " seed " << s << ": estimation " << id.report.estimation.rss_sss_percent
                << " % (floor " << studies::noise_floor_percent(est) << " %), validation "
                << v.errors.rss_sss_percent << " % (floor " << floor << " %)\n";
      for (const auto& e : id.report.parameters) {
        const auto it = truth.find(e.name);
        std::cout << "    " << e.name << " = " << e.value << " [" << e.lower95 << ", " << e.upper95
                  << "] true " << (it == truth.end() ? std::nan("") : it->second) << "\n";
      }
      for (const auto& st : id.report.starts)
        std::cout << "    start " << st.kind << " " << st.start_percent << " -> "
                  << st.final_percent << (st.distinct ? " distinct" : "") << "\n";
    }
  }
  return out;
}

void print_and_check(const std::string& method, const StudyOutcome& o) {
  std::cout << std::setprecision(4);
  o.coverage.print(std::cout, method);
  const auto [rmin, rmax] = std::minmax_element(o.ratio.begin(), o.ratio.end());
  double rmean = 0, tsum = 0, fmean = 0;
  for (double r : o.ratio) rmean += r / static_cast<double>(o.ratio.size());
  for (double f : o.floor) fmean += f / static_cast<double>(o.floor.size());
  for (double t : o.seconds) tsum += t;
  std::cout << "  records: estimation " << o.samples_estimation << " samples, validation "
            << o.samples_validation << " samples, noise floor ~" << fmean << " %\n"
            << "  validation RSS/SSS / noise floor: min " << *rmin << " mean " << rmean << " max "
            << *rmax << "\n"
            << "  identification: " << tsum << " s for " << o.seconds.size() << " fits ("
            << *std::max_element(o.seconds.begin(), o.seconds.end()) << " s the longest)\n";
  std::map<std::string, int> distinct;
  // Warnings grouped by their text with the numbers taken out.
  // (decimals and exponents only, so that indices such as threshold[3] stay).
  for (const auto& w : o.warnings) ++distinct[mask_decimals(w)];
  for (const auto& [w, count] : distinct) std::cout << "  warning x" << count << ": " << w << "\n";

  EXPECT_TRUE(o.coverage.unmatched.empty())
      << method << ": parameter names differ from the truth, e.g. " << o.coverage.unmatched.front();
  for (const auto& [name, c] : o.coverage.counts)
    EXPECT_GE(o.coverage.fraction(name), kCoverage)
        << method << " " << name << ": the truth is inside the 95 % interval in " << c.inside
        << " of " << o.coverage.fits << " seeds";
  for (std::size_t s = 0; s < o.ratio.size(); ++s)
    EXPECT_LE(o.ratio[s], kFloorFactor)
        << method << " seed " << s + 1 << ": validation RSS/SSS is " << o.ratio[s]
        << " x the noise floor " << o.floor[s] << " %";
}

// NLR and DNLRX round trips (issue 3: 40 seeds, per parameter >= 90 %, validation <= 1.2 x the
// floor on every seed).  Measured at the change that made them pass (initial-state refinement,
// weak-operator relocation and repeated global rounds in nlr.cpp; initial-state passes in
// dnlrx_identification.cpp): NLR 36-40 of 40 per parameter (pooled 298/320), DNLRX 36-40 of 40
// (pooled 528/560), validation 0.998-1.13 x the floor on every seed of both.  The narrowest
// margins are threshold[3], threshold[4] (36/40, rms z 1.2): their intervals are still about 20 %
// too narrow, which the 90 % rule tolerates but which a user should know (README).
TEST(MethodStudies, NlrRoundTripCoverageOnMaxwellSlipData) {
  const AnyModel reference = reference_model("maxwell-slip", kRate);
  const auto truth =
      std::get<Extended<MaxwellSlip<double>>>(reference.variant()).base().parameters();
  MethodOptions options;
  options.operators = truth.size();
  const auto outcome =
      run_study("maxwell-slip", studies::truth_of(truth), options, [&](const Signal& x, int seed) {
        MaxwellSlip<double> model(truth);
        UniformSource u(static_cast<std::uint64_t>(seed));
        std::vector<double> d0;
        for (double d : truth.threshold) d0.push_back(d * u());
        model.reset(std::span<const double>(d0));
        return studies::noisy_record(model, x, kSigma, static_cast<std::uint64_t>(seed),
                                     "maxwell-slip study seed " + std::to_string(seed));
      });
  print_and_check("NLR", outcome);
}

TEST(MethodStudies, DnlrxRoundTripCoverageOnDnlrxData) {
  const AnyModel reference = reference_model("dnlrx", kRate);
  const auto truth = std::get<Extended<Dnlrx<double>>>(reference.variant()).base().parameters();
  MethodOptions options;
  options.operators = truth.size();
  options.spring_order = static_cast<long>(truth.spring_order);
  options.input_order = static_cast<long>(truth.input_taps()) - 1;
  const auto outcome =
      run_study("dnlrx", studies::truth_of(truth), options, [&](const Signal& x, int seed) {
        Dnlrx<double> model(truth);
        UniformSource u(static_cast<std::uint64_t>(seed));
        std::vector<double> d0;
        for (double d : truth.threshold) d0.push_back(d * u());
        model.reset(std::span<const double>(d0));
        return studies::noisy_record(model, x, kSigma, static_cast<std::uint64_t>(seed),
                                     "dnlrx study seed " + std::to_string(seed));
      });
  print_and_check("DNLRX", outcome);
}

TEST(MethodStudies, LgRoundTripCoverageOnLuGreData) {
  const AnyModel reference = reference_model("lugre", kRate);
  const auto truth = std::get<Extended<LuGre<double>>>(reference.variant()).base().parameters();
  const auto outcome =
      run_study("lugre", studies::truth_of(truth), MethodOptions{}, [&](const Signal& x, int seed) {
        LuGre<double> model(truth);
        UniformSource u(static_cast<std::uint64_t>(seed));
        // Anywhere between the two sliding states at rest, z = +-Fs / sigma0.
        model.reset(u() * truth.static_force / truth.stiffness);
        return studies::noisy_record(model, x, kSigma, static_cast<std::uint64_t>(seed),
                                     "lugre study seed " + std::to_string(seed));
      });
  print_and_check("LG", outcome);
}

// ---- 2. The paper's ranking on GMS data ------------------------------------------------------

struct MethodRow {
  std::string method;
  std::string orders;
  double estimation = 0, validation = 0, validation_floor = 0, seconds = 0;
  std::size_t parameters = 0;
  std::vector<std::string> warnings;
  std::string error;                        // what the method threw, if it did
  double validation_loaded = std::nan("");  // RSS/SSS % over the loaded samples only
  double rms = 0, max_abs = 0;              // validation [N]
};

std::string orders_of(const IdentificationReport& rep) {
  for (const auto& row : rep.selection)
    if (row.selected)
      return "M=" + std::to_string(row.operators) + " n=" + std::to_string(row.spring_order) +
             " nx=" + std::to_string(row.input_order);
  return "-";
}

// Runs every method; a method that throws is recorded (row.error) and the others still run.
// `loaded` (optional, per validation sample) marks the samples the loaded-only error counts.
std::vector<MethodRow> compare_methods(const Record& estimation, const Record& validation,
                                       const MethodOptions& options,
                                       const std::vector<bool>& loaded = {}) {
  std::vector<MethodRow> rows;
  for (const char* type : {"lugre", "maxwell-slip", "dnlrx"}) {
    MethodRow row;
    row.method = method_name(type);
    const auto t0 = std::chrono::steady_clock::now();
    try {
      const IdentifiedModel id = identify_model(type, estimation, options);
      row.seconds = seconds_since(t0);
      row.orders = std::string(type) == "lugre" ? "-" : orders_of(id.report);
      row.parameters = id.report.parameters.size();
      row.estimation = id.report.estimation.rss_sss_percent;
      const Validation v = validate_model(id.model, validation);
      row.validation = v.errors.rss_sss_percent;
      row.validation_floor = v.noise_floor_percent;
      row.rms = v.errors.rms;
      row.max_abs = v.errors.max_abs;
      row.warnings = id.report.warnings;
      if (!loaded.empty()) {
        std::vector<double> measured, simulated;
        for (std::size_t k = 0; k < loaded.size(); ++k)
          if (loaded[k])
            measured.push_back(validation.force[k]), simulated.push_back(v.simulated[k]);
        row.validation_loaded = compute_errors(measured, simulated).rss_sss_percent;
      }
    } catch (const std::exception& e) {
      row.seconds = seconds_since(t0);
      row.error = e.what();
      row.estimation = row.validation = std::nan("");
    }
    rows.push_back(row);
  }
  return rows;
}

void print_table(const std::vector<MethodRow>& rows) {
  const bool loaded =
      std::isfinite(rows.front().validation_loaded) || std::isfinite(rows.back().validation_loaded);
  std::cout << "  method  orders            params  estimation %  validation %  (floor %)"
            << "   rms [N]  max|e| [N]" << (loaded ? "  loaded %" : "") << "  seconds\n";
  for (const auto& r : rows) {
    std::cout << "  " << std::left << std::setw(7) << r.method << " " << std::setw(17) << r.orders
              << std::right << std::setw(7) << r.parameters << std::setw(14) << std::setprecision(4)
              << r.estimation << std::setw(14) << r.validation << std::setw(11)
              << r.validation_floor << std::setw(10) << r.rms << std::setw(12) << r.max_abs;
    if (loaded) std::cout << std::setw(10) << r.validation_loaded;
    std::cout << std::setw(9) << std::setprecision(3) << r.seconds << "\n";
  }
  for (const auto& r : rows) {
    if (!r.error.empty()) std::cout << "  " << r.method << " FAILED: " << r.error << "\n";
    for (const auto& w : r.warnings) std::cout << "  " << r.method << " warning: " << w << "\n";
  }
}

TEST(MethodStudies, PaperRankingOnGmsData) {
  const std::filesystem::path data = std::filesystem::path(FRICTION_SOURCE_DIR) / "data";
  const Record est = read_record(data / "estimation.csv");
  const Record val = read_record(data / "validation.csv");
  std::cout << "GMS reference system (data/make-data.sh): estimation " << est.size()
            << " samples, validation " << val.size() << " samples\n";
  const auto rows = compare_methods(est, val, MethodOptions{});
  print_table(rows);
  ASSERT_EQ(rows.size(), 3u);
  const double lg = rows[0].validation, nlr = rows[1].validation, dnlrx = rows[2].validation;
  for (const auto& r : rows) ASSERT_TRUE(r.error.empty()) << r.method << ": " << r.error;
  for (const auto& r : rows) ASSERT_TRUE(std::isfinite(r.validation)) << r.method;
  EXPECT_LT(dnlrx, nlr) << "DNLRX " << dnlrx << " % is not below NLR " << nlr << " %";
  EXPECT_LT(nlr, lg) << "NLR " << nlr << " % is not below LG " << lg << " %";
}

// ---- 3. The tribometer record ----------------------------------------------------------------

TEST(MethodStudies, TribometerRecordAllMethodsRun) {
  const std::filesystem::path file =
      std::filesystem::path(FRICTION_SHARED_DIR) / "data" / "tribometer" / "reciprocating.csv";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "tribometer record absent: " << file.string();
  const Record all = read_record(file);
  const auto& c = all.conditioning;
  std::cout << "tribometer: " << all.size() << " samples, force sign " << c.force_sign
            << (c.force_sign_decided ? " (decided from the data)" : " (undecided)") << ", "
            << c.gaps.size() << " sampling gaps, nominal period " << c.nominal_period
            << " s, displacement resolution " << c.displacement_resolution << " m"
            << (c.displacement_quantised ? " (quantised)" : "") << ", force noise " << c.force_noise
            << " N\n";
  for (const auto& w : c.warnings) std::cout << "  conditioning: " << w << "\n";
  const std::size_t half = all.size() / 2;
  const Record est = all.slice(0, half), val = all.slice(half, all.size());
  std::cout << "  estimation t = " << est.time.front() << ".." << est.time.back()
            << " s, validation t = " << val.time.front() << ".." << val.time.back() << " s\n";
  // The normal load is on from t ~ 7.4 s to t ~ 210.2 s; friction vanishes outside, which no
  // method models.  The loaded-only column counts the validation samples whose normal force is
  // above half its median (a rule from the data, not from the times).
  std::vector<bool> loaded(val.size(), true);
  if (val.has_normal()) {
    std::vector<double> n = all.normal;
    std::nth_element(n.begin(), n.begin() + static_cast<std::ptrdiff_t>(n.size() / 2), n.end());
    const double median = n[n.size() / 2];
    for (std::size_t k = 0; k < val.size(); ++k) loaded[k] = val.normal[k] > 0.5 * median;
  }
  const auto rows = compare_methods(est, val, MethodOptions{}, loaded);
  print_table(rows);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(c.force_sign, -1) << "the record measures the force on the specimen";
  for (const auto& r : rows) {
    EXPECT_TRUE(r.error.empty()) << r.method << " threw: " << r.error;
    EXPECT_TRUE(std::isfinite(r.estimation)) << r.method;
    EXPECT_TRUE(std::isfinite(r.validation)) << r.method;
  }
}

}  // namespace
}  // namespace test_method_studies
