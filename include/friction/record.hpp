// A measured or synthetic displacement-force record.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace friction {

/// One sampling interval that differs from the nominal period (see signals.hpp).
struct SamplingGap {
  std::size_t index = 0;  ///< the interval (t[index-1], t[index]]
  double dt = 0.0;        ///< its length [s]
};

/// What signal conditioning found and did (filled by `condition_record`, signals.hpp).  The
/// numbers describe the record as stored, i.e. in SI units and in the model's sign convention.
struct Conditioning {
  // Force sign (methods.md, sign convention).
  int force_sign = 1;               ///< stored force = force_sign * force as read from the source
  bool force_sign_given = false;    ///< true when the caller imposed the sign (+1/-1), not `auto`
  bool force_sign_decided = false;  ///< auto mode: the data decided it (false: kept +1, warned)
  std::size_t sliding_samples = 0;  ///< samples used to decide the sign
  double sliding_velocity = 0.0;    ///< |v| above which a sample counted as sliding [m/s]

  // Sampling.
  double nominal_period = 0.0;    ///< median sampling interval [s]
  double min_period = 0.0;        ///< shortest interval [s]
  double max_period = 0.0;        ///< longest interval [s]
  double period_tolerance = 0.0;  ///< relative tolerance of the regularity rule
  bool irregular = false;         ///< some interval deviates by more than the tolerance
  std::vector<SamplingGap> gaps;  ///< every such interval, in time order

  // Noise and resolution, for identification (bounds on thresholds, the error floor).
  double displacement_resolution = 0.0;  ///< [m]: the quantum, or the noise level if unquantised
  bool displacement_quantised = false;   ///< an encoder-like quantum was found
  /// The displacement the models see (sample_derivatives.hpp, "The displacement the models see"):
  /// the value at t_k of a local polynomial of this half width and degree (1 and 2: as measured).
  std::size_t displacement_half_width = 1;
  std::size_t displacement_degree = 2;
  double force_noise = 0.0;  ///< standard deviation of the force noise [N]; 0 if none

  std::vector<std::string> warnings;  ///< one sentence each, for the document and stderr
};

/// Signals of one experiment in SI units and the model's sign convention (methods.md).
struct Record {
  std::vector<double> time;          ///< [s], strictly increasing
  std::vector<double> displacement;  ///< x [m], as the models see it (signal conditioning)
  /// x as measured [m] when conditioning replaced `displacement` by its local-polynomial
  /// estimate (an encoder's staircase); empty otherwise.  The derivative windows come from it.
  std::vector<double> measured_displacement;
  std::vector<double> force;   ///< F [N]; empty when the record has no force (simulate)
  std::vector<double> normal;  ///< normal force [N]; empty when not recorded
  std::string source;          ///< file name or description, for messages

  /// Line of sample 0 in `source` (1-based; sample k is on line first_line + k because blank
  /// lines are allowed only at the end of a file); 0 when the record was not read from text.
  long first_line = 0;
  /// Header names of the columns the signals came from (empty when not read from a file).
  std::string time_column, displacement_column, force_column, normal_column;
  /// Result of signal conditioning; default (nothing done) for records built in memory.
  Conditioning conditioning;

  std::size_t size() const noexcept { return time.size(); }
  bool has_force() const noexcept { return !force.empty(); }
  bool has_normal() const noexcept { return !normal.empty(); }
  /// The displacement as measured (the one the derivative windows are chosen on).
  const std::vector<double>& measured() const noexcept {
    return measured_displacement.empty() ? displacement : measured_displacement;
  }

  /// Line in `source` of sample k, or 0 when unknown.
  long line_of(std::size_t k) const noexcept {
    return first_line > 0 ? first_line + static_cast<long>(k) : 0;
  }

  /// Samples [begin, end) as a record of their own (e.g. an estimation/validation split).  Keeps
  /// source, columns and conditioning (which describe the whole record) and the line numbers.
  Record slice(std::size_t begin, std::size_t end) const {
    Record r;
    if (end > size()) end = size();
    if (begin > end) begin = end;
    const auto cut = [&](const std::vector<double>& v) {
      return v.empty() ? std::vector<double>{}
                       : std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(begin),
                                             v.begin() + static_cast<std::ptrdiff_t>(end));
    };
    r.time = cut(time);
    r.displacement = cut(displacement);
    r.measured_displacement = cut(measured_displacement);
    r.force = cut(force);
    r.normal = cut(normal);
    r.source = source;
    r.first_line = first_line > 0 ? first_line + static_cast<long>(begin) : 0;
    r.time_column = time_column;
    r.displacement_column = displacement_column;
    r.force_column = force_column;
    r.normal_column = normal_column;
    r.conditioning = conditioning;
    return r;
  }
};

}  // namespace friction
