// A measured or synthetic displacement-force record.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace friction {

/// Signals of one experiment in SI units and the model's sign convention (methods.md).
struct Record {
  std::vector<double> time;          ///< [s], strictly increasing
  std::vector<double> displacement;  ///< x [m]
  std::vector<double> force;         ///< F [N]; empty when the record has no force (simulate)
  std::vector<double> normal;        ///< normal force [N]; empty when not recorded
  std::string source;                ///< file name or description, for messages

  std::size_t size() const noexcept { return time.size(); }
  bool has_force() const noexcept { return !force.empty(); }
  bool has_normal() const noexcept { return !normal.empty(); }
};

}  // namespace friction
