// Fits on concurrent threads give the results they give alone, bit for bit.
//
// `compare` runs its methods on concurrent threads and `diagnose` its candidates; nothing in an
// identification may touch state another one sees (a process-wide random generator, a cache
// without a lock, a static scratch buffer).  A race of that kind shows as a different result on
// some runs, or not at all on a quiet machine: so this test is also run under ThreadSanitizer
// (scripts/run-tests.sh), which reports the race itself.  The diagnosis and LG's global stage
// have their own tests of the same kind (test_diagnose, test_lg).  DNLRX takes NLR's report from
// the thread that identified NLR, as in compare.  NLR runs the starts of one M concurrently.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "friction/csv.hpp"
#include "friction/methods.hpp"

namespace friction {
namespace test_concurrency {
namespace {

// Every number of the model and the validation error, printed exactly (%a).
std::string fingerprint(const IdentifiedModel& m, const Validation& v) {
  char error[64];
  std::snprintf(error, sizeof error, "%a", v.errors.rss_sss_percent);
  return m.model.to_json().dump() + " " + error;
}

TEST(Concurrency, TheThreeMethodsOnConcurrentThreadsGiveTheirSequentialResults) {
  const std::filesystem::path data = std::filesystem::path(FRICTION_SOURCE_DIR) / "data";
  // Samples 4000-6000 of each record of data/: presliding loops and sliding at two speeds, short
  // enough for TSan.  (The first 2000, which slide at one speed, cost LG 1.1 s in Release, four
  // times as long as here, on an ill-posed fit that ends at its iteration limit: 51 s for this
  // test under TSan, the pass's long pole.)
  const Record est = read_record(data / "estimation.csv").slice(4000, 6000);
  const Record val = read_record(data / "validation.csv").slice(4000, 6000);
  const std::array<std::string, 3> types{"lugre", "maxwell-slip", "dnlrx"};
  const auto run = [&](const std::string& type) {
    const IdentifiedModel m = identify_model(type, est);
    return fingerprint(m, validate_model(m.model, val));
  };

  std::array<std::string, 3> alone, together;
  for (std::size_t i = 0; i < types.size(); ++i) alone[i] = run(types[i]);
  {
    // As compare runs them: DNLRX's thread takes NLR's order selection from the report NLR's
    // thread hands over (MethodOptions::maxwell_slip_report), and must end where DNLRX ends
    // alone, with its own NLR run.
    std::promise<IdentificationReport> handed;
    std::vector<std::thread> threads;
    threads.emplace_back([&] { together[0] = run(types[0]); });
    threads.emplace_back([&] {
      const IdentifiedModel m = identify_model(types[1], est);
      handed.set_value(m.report);
      together[1] = fingerprint(m, validate_model(m.model, val));
    });
    threads.emplace_back([&] {
      const IdentificationReport report = handed.get_future().get();
      MethodOptions o;
      o.maxwell_slip_report = &report;
      const IdentifiedModel m = identify_model(types[2], est, o);
      together[2] = fingerprint(m, validate_model(m.model, val));
    });
    for (auto& t : threads) t.join();
  }
  for (std::size_t i = 0; i < types.size(); ++i) {
    EXPECT_FALSE(alone[i].empty()) << types[i];
    EXPECT_EQ(together[i], alone[i]) << types[i];
  }
  // Two fits of the same method at once share every static of its code path.
  std::array<std::string, 2> twins;
  {
    std::thread a([&] { twins[0] = run("maxwell-slip"); });
    std::thread b([&] { twins[1] = run("maxwell-slip"); });
    a.join();
    b.join();
  }
  EXPECT_EQ(twins[0], alone[1]);
  EXPECT_EQ(twins[1], alone[1]);
}

TEST(Concurrency, NlrStartsOnSeveralThreadsGiveTheResultOfOne) {
  // NLR's order selection runs the starts of each M concurrently (NlrOptions::threads): the
  // model, the start log (every start's thresholds, costs and iterations) and the validation
  // error must be those of one thread, bit for bit.
  const std::filesystem::path data = std::filesystem::path(FRICTION_SOURCE_DIR) / "data";
  // 1200 samples and M up to 4: both starts at most M, short enough for TSan.
  const Record est = read_record(data / "estimation.csv").slice(0, 1200);
  const Record val = read_record(data / "validation.csv").slice(0, 1200);
  const auto run = [&](unsigned threads) {
    MethodOptions o;
    o.threads = threads;
    o.max_operators = 4;
    const IdentifiedModel m = identify_model("maxwell-slip", est, o);
    std::string log;
    for (const StartLog& s : m.report.starts) {
      char line[160];
      std::snprintf(line, sizeof line, "%zu %s %a %a %d\n", s.operators, s.kind.c_str(),
                    s.start_percent, s.final_percent, s.iterations);
      log += line;
    }
    return fingerprint(m, validate_model(m.model, val)) + "\n" + log;
  };
  const std::string one = run(1);
  EXPECT_NE(one.find(" dictionary "), std::string::npos) << one;
  EXPECT_NE(one.find(" warm "), std::string::npos) << one;
  EXPECT_EQ(run(2), one);
}

}  // namespace
}  // namespace test_concurrency
}  // namespace friction
