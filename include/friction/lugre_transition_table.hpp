// LuGre transitions tabulated over the speed, for searches that run one record thousands of times.
//
// A free run of the exact step (lugre.hpp) spends most of its time in each interval's transition:
// s(v) needs (|v|/vs)^mu (a log and an exp), the decay exp(-|v| dt / s(v)) another exp, so three
// transcendental functions per sample and parameter set, where carrying the state through the
// transition costs a few multiplications.  LG's global stage runs ~4500 free runs of the record
// (CRS2 and two BOBYQA polishes, lg.hpp step 2), and measured on the bench records these
// functions were two thirds of an identification.
//
// On a record sampled at one interval dt (to rounding) the transition is a function of the speed
// alone, and a smooth one in u = ln|v|:
//
//     s(u)     = (Fc + (Fs - Fc) w(u)) / sigma0,   w = 1 / (1 + e^{mu (u - ln vs)})  (rational)
//                                                  or exp(-e^{mu (u - ln vs)})       (exponential)
//     rate(u)  = e^u / s(u),      decay(u) = exp(-dt rate(u)).
//
// w is a logistic (or a double exponential) in u whose k-th derivative is bounded by a constant
// times mu^k; decay(u) = exp(-y) with y = dt rate(u), whose derivatives in u are sums of
// y^j e^{-y} times derivatives of ln rate, bounded however stiff the relaxation is.  So the three
// quantities are computed exactly at nodes spaced h in u over the record's range of nonzero
// speeds and interpolated at each sample by the cubic through the four nearest nodes (Lagrange),
// whose error is at most h^4 max|f''''| / 24 with a constant below 1 over the nodes' interval:
// with h = 1/32 and mu <= 6 (the search's bound) the relative error of w is below 1e-6, and a
// free run's force differs from the exact step's by less than 1e-5 of its largest value on the
// tested records (test_lugre.cpp).  A sample's node and four weights depend on its speed only and
// are computed once per record; per parameter set the table costs G nodes' transitions, with
// G = (ln(vmax / vmin)) / h + 4 (~300-600 for speeds spanning 4-8 decades) instead of N.
//
// This is an approximation of the exact step, for a search's objective only: LG's local stage,
// the reported fit and every validation use the exact step.  A record sampled at irregular
// intervals, or with too few samples for the table to pay, gets no table (`usable()` false).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "friction/lugre.hpp"
#include "friction/motion.hpp"

namespace friction {

class LuGreTransitionTable {
 public:
  /// Node spacing in ln|v| (see the header comment for the error it gives).
  static constexpr double kSpacing = 1.0 / 32.0;
  /// Intervals (and, in LG's shared transitions, velocities) that agree to this relative
  /// difference count as one: time stamps and displacements written as decimals differ in their
  /// last bits from sample to sample.
  static constexpr double kSameToRounding = 1e-9;

  /// Indexes the motions of a record (motion.hpp: sample 0 has dt = 0; the others the interval
  /// before them).  The level and asymmetry of every motion must be nominal (1, 0): the table is
  /// for the plain model's search.
  explicit LuGreTransitionTable(std::span<const Motion<double>> motions) {
    const std::size_t n = motions.size();
    if (n < 2) return;
    std::vector<double> dts;
    double vmin = std::numeric_limits<double>::infinity(), vmax = 0;
    for (std::size_t k = 1; k < n; ++k) {
      if (motions[k].level != 1.0 || motions[k].asymmetry != 0.0) return;
      dts.push_back(motions[k].dt);
      const double speed = std::abs(motions[k].velocity);
      if (speed > 0) vmin = std::min(vmin, speed), vmax = std::max(vmax, speed);
    }
    if (!(vmax > 0) || !std::isfinite(vmax)) return;
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2),
                     dts.end());
    dt_ = dts[dts.size() / 2];
    if (!(dt_ > 0)) return;
    // One interval to rounding: time stamps written as decimals differ in their last bits.
    for (std::size_t k = 1; k < n; ++k)
      if (std::abs(motions[k].dt - dt_) > kSameToRounding * dt_) return;
    u0_ = std::log(vmin) - kSpacing;
    const std::size_t nodes =
        static_cast<std::size_t>(std::ceil((std::log(vmax) - u0_) / kSpacing)) + 3;
    // The table pays when it has well fewer nodes than the record has samples.
    if (4 * nodes > n) return;
    speed_.resize(nodes);
    for (std::size_t j = 0; j < nodes; ++j)
      speed_[j] = std::exp(u0_ + static_cast<double>(j) * kSpacing);
    sample_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      Sample& s = sample_[k];
      s.velocity = motions[k].velocity;
      const double speed = std::abs(s.velocity);
      if (k == 0 || !(speed > 0)) continue;  // at rest: direction 0, nothing interpolated
      s.direction = s.velocity > 0 ? 1 : -1;
      // Stencil nodes j-1 .. j+2 around the sample's position u in [u_j, u_j+1).
      const double pos = (std::log(speed) - u0_) / kSpacing;
      const std::size_t j = std::clamp<std::size_t>(static_cast<std::size_t>(pos), 1, nodes - 3);
      const double t = pos - static_cast<double>(j);  // in [0, 1) (clamped stencils extrapolate)
      s.first = static_cast<std::uint32_t>(j - 1);
      // Cubic Lagrange weights of the nodes at -1, 0, 1, 2 for position t.
      s.weight = {-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2,
                  -(t + 1) * t * (t - 2) / 2, (t + 1) * t * (t - 1) / 6};
    }
    usable_ = true;
  }

  /// Whether the record was indexed (one sampling interval, enough samples).
  bool usable() const noexcept { return usable_; }
  std::size_t nodes() const noexcept { return speed_.size(); }

  /// Free run of `model` (state as it is) over the indexed record, force written to out[0, N).
  void run(LuGre<double>& model, double* out) const {
    const LuGreParameters<double>& p = model.parameters();
    const std::size_t g = speed_.size();
    node_.resize(g);
    for (std::size_t j = 0; j < g; ++j) {
      const auto tr = model.transition(Motion<double>{0.0, speed_[j], dt_});
      node_[j] = {tr.z_inf, tr.decay, tr.rate};
    }
    for (std::size_t k = 0; k < sample_.size(); ++k) {
      const Sample& s = sample_[k];
      LuGre<double>::Transition tr{0.0, 1.0, 0.0, p.viscous * s.velocity};
      if (s.direction != 0) {
        const Node* a = &node_[s.first];
        double z = 0, decay = 0, rate = 0;
        for (std::size_t i = 0; i < 4; ++i) {
          z += s.weight[i] * a[i].s;
          decay += s.weight[i] * a[i].decay;
          rate += s.weight[i] * a[i].rate;
        }
        tr.z_inf = s.direction * z;
        tr.decay = std::clamp(decay, 0.0, 1.0);
        tr.rate = rate;
      }
      out[k] = model.step(tr);
    }
  }

 private:
  struct Sample {
    double velocity = 0;
    double direction = 0;
    std::uint32_t first = 0;
    std::array<double, 4> weight{};
  };
  struct Node {
    double s, decay, rate;
  };
  bool usable_ = false;
  double dt_ = 0, u0_ = 0;
  std::vector<double> speed_;
  std::vector<Sample> sample_;
  mutable std::vector<Node> node_;
};

}  // namespace friction
