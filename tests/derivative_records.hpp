// The records both derivative test programs draw from the independent simulator (tests/study):
// seed s picks the excitation family (s mod 3) and the simulator's seed.
#pragma once

#include <cstdint>

#include "study_design.hpp"

namespace friction::testing {

inline truth::StudyRecord derivative_record(std::uint64_t seed) {
  truth::RecordSpec spec;
  spec.id = "derivatives";
  spec.family = static_cast<truth::Family>(seed % 3);
  spec.seed = seed * 2654435761u;
  // The records these studies were measured on (their figures are quoted in the README).
  spec.validation = truth::ValidationDesign::independent_design;
  return truth::make_record(spec);
}

}  // namespace friction::testing
