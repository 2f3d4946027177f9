// A trace of the independent simulator (tests/study) as the library's Record, in SI as simulated:
// the test programs that fit its records read them this way.
#pragma once

#include <cstddef>
#include <vector>

#include "friction/record.hpp"
#include "truth_simulator.hpp"

namespace friction::testing {

/// Samples `begin` to the end of `t` (the normal force too, when the trace has one).
inline Record record_of(const truth::Trace& t, std::size_t begin = 0) {
  const auto from = [begin](const std::vector<double>& v) {
    return std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(begin), v.end());
  };
  Record r;
  r.time = from(t.time);
  r.displacement = from(t.position);
  r.force = from(t.force);
  if (!t.normal.empty()) r.normal = from(t.normal);
  r.source = "simulated";
  return r;
}

}  // namespace friction::testing
