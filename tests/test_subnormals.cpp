// Subnormal numbers flushed to zero while the library computes (src/subnormals.hpp): inside the
// guard a product below 2.2e-308 is zero and a subnormal input counts as zero; outside it, and
// after it, the caller's mode is back, whether the guarded code returned or threw; a public
// driver leaves the caller's mode as it found it; parallel_for's workers compute in the mode of
// the thread that started them.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "../src/parallel_for.hpp"
#include "../src/subnormals.hpp"
#include "friction/methods.hpp"
#include "friction/record.hpp"

namespace test_subnormals {
namespace {

using friction::detail::floating_point_mode;
using friction::detail::SubnormalsFlushed;

bool has_flush_mode() {
  const unsigned long long m = floating_point_mode();
  return friction::detail::with_subnormals_flushed(m) != m;
}

// Through volatile, so that the compiler cannot fold the products at compile time.
double tiny_product() {
  volatile double a = 1e-300, b = 1e-10;
  return a * b;
}

double subnormal_times_one(double subnormal) {
  volatile double a = subnormal, b = 1.0;
  return a * b;
}

TEST(Subnormals, TheGuardFlushesAndRestoresTheCallersMode) {
  if (!has_flush_mode()) GTEST_SKIP() << "no flush-to-zero mode on this hardware";
  const unsigned long long before = floating_point_mode();
  const double subnormal = tiny_product();
  ASSERT_GT(subnormal, 0.0) << "the caller's mode already flushes: the test needs IEEE mode";
  ASSERT_LT(subnormal, std::numeric_limits<double>::min());
  {
    const SubnormalsFlushed outer;
    EXPECT_EQ(tiny_product(), 0.0);                  // results flushed
    EXPECT_EQ(subnormal_times_one(subnormal), 0.0);  // inputs taken as zero
    {
      const SubnormalsFlushed nested;
      EXPECT_EQ(tiny_product(), 0.0);
    }
    EXPECT_EQ(tiny_product(), 0.0);  // the nested guard restored the outer one's mode
  }
  EXPECT_EQ(floating_point_mode(), before);
  EXPECT_EQ(tiny_product(), subnormal);
  try {
    const SubnormalsFlushed guard;
    throw std::runtime_error("leaving by an exception");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(floating_point_mode(), before);
  EXPECT_EQ(tiny_product(), subnormal);
}

// Linux threads start with their creator's mode, so there this passes even without
// parallel_for's hand-over; it guards systems whose threads start in the default mode.
TEST(Subnormals, ParallelForWorkersComputeInTheCallersMode) {
  if (!has_flush_mode()) GTEST_SKIP() << "no flush-to-zero mode on this hardware";
  constexpr std::size_t kItems = 32;
  for (const bool flushed : {true, false}) {
    std::vector<double> products(kItems, -1.0);
    std::vector<std::thread::id> ran_on(kItems);
    const auto run = [&] {
      friction::detail::parallel_for(kItems, 4, [&](std::size_t i) {
        // Long enough that the workers take their share of the items.
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        products[i] = tiny_product();
        ran_on[i] = std::this_thread::get_id();
      });
    };
    if (flushed) {
      const SubnormalsFlushed guard;
      run();
    } else {
      run();
    }
    const std::set<std::thread::id> threads(ran_on.begin(), ran_on.end());
    EXPECT_GE(threads.size(), 2u) << "the items all ran on one thread";
    for (std::size_t i = 0; i < kItems; ++i)
      EXPECT_EQ(products[i], flushed ? 0.0 : tiny_product()) << "item " << i << ", flushed "
                                                               << flushed;
  }
}

// A controller that links the library keeps its mode across an identification and a validation.
TEST(Subnormals, APublicDriverLeavesTheCallersModeAsItFoundIt) {
  if (!has_flush_mode()) GTEST_SKIP() << "no flush-to-zero mode on this hardware";
  friction::Record r;
  const double dt = 1e-3;
  for (int k = 0; k < 400; ++k) {
    const double t = k * dt;
    const double x = 1e-4 * std::sin(2 * M_PI * 2.0 * t);
    const double v = 1e-4 * 2 * M_PI * 2.0 * std::cos(2 * M_PI * 2.0 * t);
    r.time.push_back(t);
    r.displacement.push_back(x);
    r.force.push_back(std::tanh(v / 1e-4) + 5.0 * v);
  }
  const unsigned long long before = floating_point_mode();
  friction::MethodOptions o;
  o.max_operators = 3;
  const friction::IdentifiedModel m = friction::identify_model("maxwell-slip", r, o);
  EXPECT_EQ(floating_point_mode(), before);
  (void)friction::validate_model(m.model, r);
  EXPECT_EQ(floating_point_mode(), before);
  EXPECT_GT(tiny_product(), 0.0);
}

}  // namespace
}  // namespace test_subnormals
