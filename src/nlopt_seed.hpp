// The one place the library seeds NLopt's random numbers (the CRS2 global stage of LG; NLR's
// global stage, threshold moves, draws none).
//
// NLopt 2.7 has no per-optimiser seed: nlopt::srand sets the Mersenne-Twister generator that every
// stochastic algorithm draws from (nlopt::opt::set_param has no seed parameter).  In Debian's
// libnlopt.so.0 (2.7.1) that generator is thread-local (the library carries .tdata/.tbss sections:
// mt19937ar.c's state is declared THREADLOCAL), so a global stage is deterministic when it seeds
// right before it optimises, on the thread that optimises -- which is what every caller does
// through seed_nlopt, and why the results do not depend on the order in which stages run (the
// baseline, the reference fit with one more operator, the restart of identify --extension).
//
// The lock that seed_nlopt returns keeps a NLopt built WITHOUT thread-local storage (a process-wide
// generator) deterministic too: hold it from the seed to the end of optimize().  For issue 8
// (concurrent candidates and stages): the candidate fits of diagnose use no NLopt (Ceres only),
// so they never take this lock; stages that do run NLopt on several threads are serialised by it.
// With the thread-local generator that serialisation is not needed for determinism -- issue 8 may
// drop the lock after checking the library it links (test_lg runs two LG identifications
// concurrently and compares them bit for bit with a serial run).
#pragma once

#include <nlopt.hpp>

#include <mutex>

namespace friction::detail {

/// Seeds NLopt's generator for the calling thread; keep the returned lock until optimize() ends.
[[nodiscard]] inline std::unique_lock<std::mutex> seed_nlopt(unsigned long seed) {
  static std::mutex generator;
  std::unique_lock<std::mutex> lock(generator);
  nlopt::srand(seed);
  return lock;
}

}  // namespace friction::detail
