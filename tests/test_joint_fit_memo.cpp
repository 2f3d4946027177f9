// The joint-fit memory of a diagnosis (src/joint_fit_memo.hpp): a fit asked again with the same
// arguments is the fit made before, bit for bit, without being made again; an argument changed in
// its last bit, anywhere, makes a new fit, the one fit_extended_slip makes for it; another record
// is never served from the memory.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "../src/joint_fit_memo.hpp"
#include "diagnose_support.hpp"
#include "friction/extension_fit.hpp"

namespace friction {
namespace {

using testing::Excitation;
using testing::Injected;
using testing::Injection;

double next_up(double v) { return std::nextafter(v, 2.0 * std::abs(v) + 1.0); }

void expect_same_fit(const ExtendedSlipFit& a, const ExtendedSlipFit& b, const std::string& what) {
  ASSERT_EQ(a.ok, b.ok) << what;
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.rss), std::bit_cast<std::uint64_t>(b.rss)) << what;
  ASSERT_EQ(a.base.size(), b.base.size()) << what;
  for (std::size_t i = 0; i < a.base.size(); ++i) {
    EXPECT_EQ(a.base.stiffness[i], b.base.stiffness[i]) << what << " k" << i;
    EXPECT_EQ(a.base.threshold[i], b.base.threshold[i]) << what << " Delta" << i;
  }
  EXPECT_EQ(a.rho, b.rho) << what;
  std::vector<double> pa, pb;
  a.ext.for_each_parameter([&](Effect, std::string_view, const double& v) { pa.push_back(v); });
  b.ext.for_each_parameter([&](Effect, std::string_view, const double& v) { pb.push_back(v); });
  EXPECT_EQ(pa, pb) << what;
  EXPECT_EQ(a.at_bound, b.at_bound) << what;
}

TEST(JointFitMemo, AFitAskedAgainIsTheFitMadeAndAnyChangedBitMakesANewOne) {
  Excitation ex;
  const std::vector<Injection> effects{{Injected::viscous, 40.0}, {Injected::offset, 0.05}};
  const Record r = testing::with_noise(testing::make_clean(effects, ex, 1500, 0.0), 2e-3, 21);
  const Record other = testing::with_noise(testing::make_clean(effects, ex, 1500, 0.0), 2e-3, 22);
  // A start off the truth (the support system's 4 operators, each moved), so the fits iterate.
  MaxwellSlipParameters<double> base;
  base.stiffness = {3.6e4, 3.3e4, 1.7e4, 1.2e4};
  base.threshold = {1.2e-6, 2.6e-6, 8e-6, 1.4e-5};
  const std::vector<double> rho{0.1, -0.2, 0.0, 0.3};
  ExtensionParameters<double> ext;
  ext.reference_force = base.sliding_force();
  ext.viscous.emplace();
  ext.viscous->viscous = 25.0;
  ext.offset.emplace();
  ext.offset->offset = 0.01;
  const int iterations = 20;

  extension_detail::JointFitMemo memo(r);
  const ExtendedSlipFit first = memo.fit(r, base, rho, ext, iterations);
  ASSERT_TRUE(first.ok);
  EXPECT_EQ(memo.made(), 1u);
  expect_same_fit(first, fit_extended_slip(r, base, rho, ext, false, iterations), "direct");
  expect_same_fit(memo.fit(r, base, rho, ext, iterations), first, "again");
  EXPECT_EQ(memo.made(), 1u);

  // Each argument changed in its last bit: a new fit, fit_extended_slip's.
  std::size_t made = 1;
  const auto expect_new = [&](const MaxwellSlipParameters<double>& b, const std::vector<double>& s,
                              const ExtensionParameters<double>& e, int it, const char* what) {
    const ExtendedSlipFit f = memo.fit(r, b, s, e, it);
    EXPECT_EQ(memo.made(), ++made) << what;
    expect_same_fit(f, fit_extended_slip(r, b, s, e, false, it), what);
  };
  MaxwellSlipParameters<double> b2 = base;
  b2.threshold[2] = next_up(b2.threshold[2]);
  expect_new(b2, rho, ext, iterations, "a threshold");
  std::vector<double> rho2 = rho;
  rho2[3] = next_up(rho2[3]);
  expect_new(base, rho2, ext, iterations, "a deflection");
  ExtensionParameters<double> e2 = ext;
  e2.offset->offset = next_up(e2.offset->offset);
  expect_new(base, rho, e2, iterations, "a piece's parameter");
  ExtensionParameters<double> e3 = ext;
  e3.reference_force = next_up(e3.reference_force);
  expect_new(base, rho, e3, iterations, "the reference force");
  ExtensionParameters<double> e4 = ext;  // the same numbers, another piece holding one of them
  e4.offset.reset();
  e4.drift.emplace();
  e4.drift->relative_rate = ext.offset->offset;
  expect_new(base, rho, e4, iterations, "another piece");
  expect_new(base, rho, ext, iterations + 1, "the iteration cap");

  // Another record: fitted, never remembered or served.
  const ExtendedSlipFit f = memo.fit(other, base, rho, ext, iterations);
  EXPECT_EQ(memo.made(), made);
  expect_same_fit(f, fit_extended_slip(other, base, rho, ext, false, iterations), "other record");

  // The memory keeps the latest kKept fits: the first is long gone after as many more.
  for (std::size_t j = 0; j < extension_detail::JointFitMemo::kKept; ++j) {
    std::vector<double> s = rho;
    s[0] = 0.01 * static_cast<double>(j + 1);
    memo.fit(r, base, s, ext, iterations);
  }
  made += extension_detail::JointFitMemo::kKept;
  EXPECT_EQ(memo.made(), made);
  expect_same_fit(memo.fit(r, base, rho, ext, iterations), first, "made again");
  EXPECT_EQ(memo.made(), made + 1);
}

}  // namespace
}  // namespace friction
