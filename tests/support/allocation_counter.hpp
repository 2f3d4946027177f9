// Counts heap allocations made through global operator new, to show that `step` allocates nothing.
#pragma once

#include <cstddef>

namespace friction::testing {

/// Number of global operator new calls since the program started.
std::size_t allocations_so_far() noexcept;

/// Allocations made between construction and `count()`.
class AllocationCounter {
 public:
  AllocationCounter() noexcept : start_(allocations_so_far()) {}
  std::size_t count() const noexcept { return allocations_so_far() - start_; }

 private:
  std::size_t start_;
};

}  // namespace friction::testing
