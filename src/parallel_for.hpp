// Internal: the fixed pool that diagnose's candidate fits and compare's methods share (not
// installed).
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <span>
#include <thread>
#include <vector>

#include "subnormals.hpp"

namespace friction::detail {

/// Calls body(i) once for every i in [0, count) on min(count, threads) threads, the calling
/// thread among them (threads 0: one per core).  The indices are handed out from a shared
/// counter in the order `order` gives (a permutation of [0, count), e.g. the costliest first;
/// empty: ascending), so which thread runs which index varies, and each body must write only its
/// own slot: then the result does not depend on the thread count.  An exception from a body is
/// kept and, after all have finished, the one of the lowest index is rethrown.
template <class Body>
void parallel_for(std::size_t count, unsigned threads, Body&& body,
                  std::span<const std::size_t> order = {}) {
  std::atomic<std::size_t> next{0};
  std::vector<std::exception_ptr> failed(count);
  auto work = [&] {
    for (std::size_t k; (k = next.fetch_add(1)) < count;) {
      const std::size_t i = order.empty() ? k : order[k];
      try {
        body(i);
      } catch (...) {
        failed[i] = std::current_exception();
      }
    }
  };
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t n = std::min<std::size_t>(threads ? threads : cores, count);
  // The workers compute in the caller's floating-point mode (subnormals.hpp), as the caller's
  // own share does: the same numbers on any thread count.
  const unsigned long long mode = floating_point_mode();
  std::vector<std::thread> pool;
  for (std::size_t k = 1; k < n; ++k)
    pool.emplace_back([&work, mode] {
      set_floating_point_mode(mode);
      work();
    });
  work();
  for (auto& t : pool) t.join();
  for (const auto& f : failed)
    if (f) std::rethrow_exception(f);
}

}  // namespace friction::detail
