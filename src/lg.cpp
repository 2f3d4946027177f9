// LG identification of the LuGre model (see include/friction/lg.hpp for the method).
#include "friction/lg.hpp"

#include <ceres/ceres.h>
#include <nlopt.hpp>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <optional>
#include <random>
#include <sstream>
#include <utility>

#include "bounded_solver.hpp"
#include "friction/covariance_report.hpp"
#include "friction/error.hpp"
#include "friction/lugre_transition_table.hpp"
#include "friction/motion.hpp"
#include "sample_statistics.hpp"
#include "subnormals.hpp"

namespace friction {
namespace {

constexpr std::size_t kP = LuGreParameters<double>::kSize;  // 7
constexpr double kStateBound = 1.5;                         // |u| <= 1.5, z0 = u z_ref
constexpr double kHuge = 1e30;

using Theta = std::array<double, kP>;
// The layout of Ceres' Jacobian blocks (one row per residual).
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

double quantile(std::vector<double> v, double q) {
  FRICTION_ASSERT(!v.empty());
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

// Quantile q of `v` with sample weights `w` (> 0): the smallest value whose cumulative weight
// reaches q of the total.
double weighted_quantile(const std::vector<double>& v, const std::vector<double>& w, double q) {
  FRICTION_ASSERT(!v.empty() && v.size() == w.size());
  std::vector<std::size_t> order(v.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return v[a] < v[b]; });
  const double total = std::accumulate(w.begin(), w.end(), 0.0);
  double sum = 0;
  for (std::size_t i : order) {
    sum += w[i];
    if (sum >= q * total) return v[i];
  }
  return v[order.back()];
}

// Per-sample motion of the record (motion.hpp): sample 0 has dt = 0.
std::vector<Motion<double>> motions_of(std::span<const double> time, std::span<const double> x) {
  std::vector<Motion<double>> m(x.size());
  for (std::size_t k = 0; k < x.size(); ++k) m[k] = motion_at(time, x, k);
  return m;
}

// Free run with the exact step; T = double or a Jet.
template <typename T>
void run_exact(const LuGreParameters<T>& p, const std::vector<Motion<double>>& m, const T& z0,
               T* out) {
  LuGre<T> model(p);
  model.reset(z0);
  for (std::size_t k = 0; k < m.size(); ++k)
    out[k] = model.step(Motion<T>{T(m[k].dx), T(m[k].velocity), T(m[k].dt)});
}

double rest_deflection(const LuGreParameters<double>& p) {
  return std::max(p.coulomb, p.static_force) / p.stiffness;
}

LuGreParameters<double> from_log(std::span<const double> log_theta, StribeckShape shape) {
  Theta t;
  for (std::size_t j = 0; j < kP; ++j) t[j] = std::exp(log_theta[j]);
  return LuGreParameters<double>::from_array(t, shape);
}

bool finite_parameters(const LuGreParameters<double>& p) {
  for (double v : p.to_array())
    if (!std::isfinite(v) || v <= 0.0) return false;
  return true;
}

// RSS/SSS % of a free run (exact step), +inf-like when the parameters are unusable.
//
// The global stage runs thousands of these, most of whose time is each sample's transition (its
// s(v) and exp(-|v| dt / s), LuGre::Transition).  Two ways to compute fewer:
//  * On a record whose motions repeat (an encoder's staircase at a fixed rate: data/ as measured
//    has 757 distinct (velocity, interval) pairs in 10,221 samples, the tribometer 121 in 21,289;
//    strokes at constant speeds) each distinct motion's transition is computed once per parameter
//    set and the samples only carry the state through it.  Motions count as one when their
//    velocities and intervals agree to a relative 1e-9: velocities from a displacement written in
//    decimal, or conditioned by the CLI, differ in their last bits from sample to sample of one
//    stroke (the CLI's strokes bench record: 1,096 distinct pairs to the bit, 568 motions), and
//    the transition of either differs from the other's by about that 1e-9, four decades below the
//    table's error.
//  * Otherwise, on a record sampled at one interval (a displacement without a staircase), the
//    transitions are tabulated over ln|v| and interpolated (lugre_transition_table.hpp: relative
//    force error below 1e-5, and a few hundred nodes per parameter set instead of N
//    transitions).
// The local stage and every reported figure use the exact step.
struct Objective {
  std::span<const double> force;
  std::vector<Motion<double>> motions;
  double sss = 0;
  StribeckShape shape = StribeckShape::Rational;
  mutable std::vector<double> buffer;
  std::vector<std::uint32_t> which;  // sample k's distinct motion; empty: no memo
  // What a parameter set needs of each distinct motion, kept apart so that one pass computes
  // every transition: |v|, ln|v| (0 at rest), the slip level (level times 1 + a sgn v), sgn v
  // and dt.
  std::vector<double> speed, log_speed, slip_level, direction, duration;
  // A distinct motion's transition in terms of the state's excess y = z - z_inf over its steady
  // deflection: over one interval y+ = decay y, and the force at its end (eq. 2, with dz/dt of
  // eq. 1 at the end) is F = level_force + excess_force y, with
  //     level_force = sigma0 z_inf + sigma2 v,   excess_force = decay (sigma0 - sigma1 rate).
  // The state's chain through a run of one motion is then one multiplication per sample.
  struct Carry {
    double decay, z_inf, level_force, excess_force;
  };
  mutable std::vector<Carry> carries;
  // Runs of one motion (a stroke at constant speed, a rest): run r covers samples
  // run_first[r]..run_first[r + 1] - 1 with motion run_motion[r].  The run's forces, less the
  // run's mean run_mean[r], are summed up to each sample (centred, so the difference of two sums
  // keeps its digits).  Once the state stops changing inside a run, every later sample of the run
  // has the same force, and their squared errors follow from the sums.  Memory: 20 B a sample
  // and 16 a run here, 72 B a distinct motion with the transitions.
  std::vector<std::uint32_t> run_first, run_motion;
  std::vector<double> run_mean, run_sum, run_square_sum;
  std::optional<LuGreTransitionTable> table;

  // Chooses how transitions are shared.  Measured (10,000 samples, GCC 12 -O2, one core): in the
  // memo's pass a transition costs ~15 ns and carrying the state ~1.4 ns a sample; the table's
  // nodes ~30 ns each (LuGre::transition) and interpolating and carrying ~5 ns a sample.  So the
  // table is taken when it has G nodes with 30 G + 5 N < 15 D + 1.4 N, that is when the distinct
  // motions D exceed 2 G + N / 4; otherwise the memo, which is cheaper than stepping every
  // sample (~30 ns) at any D.
  void index_motions() {
    std::vector<Motion<double>> distinct;
    which.assign(motions.size(), 0);
    // Intervals first, then velocities within each interval, each grouped by sorting and
    // sweeping: a motion joins the group whose first member it agrees with to kSame.
    constexpr double kSame = LuGreTransitionTable::kSameToRounding;
    const std::size_t n = motions.size();
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      return motions[a].dt < motions[b].dt;
    });
    std::vector<std::uint32_t> interval(n);
    std::vector<double> interval_dt;
    for (std::uint32_t k : order) {
      const double dt = motions[k].dt;
      if (interval_dt.empty() || dt - interval_dt.back() > kSame * interval_dt.back())
        interval_dt.push_back(dt);
      interval[k] = static_cast<std::uint32_t>(interval_dt.size() - 1);
    }
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      return interval[a] != interval[b] ? interval[a] < interval[b]
                                        : motions[a].velocity < motions[b].velocity;
    });
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t k = order[i];
      const Motion<double>* first = distinct.empty() ? nullptr : &distinct.back();
      const double v = motions[k].velocity;
      const bool joins = first && interval[k] == interval[order[i - 1]] &&
                         (v == first->velocity || (v * first->velocity > 0 &&
                                                   v - first->velocity <=
                                                       kSame * std::abs(first->velocity)));
      if (!joins) {
        Motion<double> m = motions[k];
        m.dt = interval_dt[interval[k]];
        distinct.push_back(m);
      }
      which[k] = static_cast<std::uint32_t>(distinct.size() - 1);
    }
    LuGreTransitionTable t(motions);
    if (t.usable() && 2 * t.nodes() + motions.size() / 4 < distinct.size()) {
      table = std::move(t);
      distinct.clear(), which.clear();
    }
    // Neither the table nor the memo steps the motions again: 56 B a sample released.
    std::vector<Motion<double>>().swap(motions);
    for (std::vector<double>* v : {&speed, &log_speed, &slip_level, &direction, &duration,
                                   &run_mean, &run_sum, &run_square_sum})
      v->clear();
    run_first.clear(), run_motion.clear();
    if (which.empty()) return;
    for (const Motion<double>& m : distinct) {
      const double dir = sign_of(m.velocity);
      speed.push_back(dir * m.velocity);
      log_speed.push_back(dir != 0.0 ? std::log(dir * m.velocity) : 0.0);
      slip_level.push_back(m.level * (1.0 + dir * m.asymmetry));
      direction.push_back(dir);
      duration.push_back(m.dt);
    }
    run_sum.assign(n, 0.0), run_square_sum.assign(n, 0.0);
    for (std::size_t first = 0; first < n;) {
      std::size_t last = first;
      while (last + 1 < n && which[last + 1] == which[first]) ++last;
      run_first.push_back(static_cast<std::uint32_t>(first));
      run_motion.push_back(which[first]);
      double mean = 0;
      for (std::size_t k = first; k <= last; ++k) mean += force[k];
      mean /= static_cast<double>(last - first + 1);
      run_mean.push_back(mean);
      double s1 = 0, s2 = 0;
      for (std::size_t k = first; k <= last; ++k) {
        s1 += force[k] - mean;
        s2 += (force[k] - mean) * (force[k] - mean);
        run_sum[k] = s1, run_square_sum[k] = s2;
      }
      first = last + 1;
    }
    run_first.push_back(static_cast<std::uint32_t>(n));
  }

  double percent(const LuGreParameters<double>& p, double z0) const {
    if (!finite_parameters(p) || !std::isfinite(z0)) return kHuge;
    double rss = 0;
    if (!which.empty()) {
      // Every distinct motion's transition in one pass (LuGre::transition's arithmetic, with
      // ln|v| kept from the indexing): the Stribeck weight (eq. 3), s(v), the rate |v| / s(v)
      // and the decay over the interval.
      const double log_vs = std::log(p.stribeck_velocity);
      const double dip = p.static_force - p.coulomb;
      carries.resize(speed.size());
      for (std::size_t i = 0; i < speed.size(); ++i) {
        double z_inf = 0.0, rate = 0.0, decay = 1.0;  // at rest
        if (speed[i] != 0.0) {
          const double weight = stribeck_weight_of_log_ratio(p, log_speed[i] - log_vs);
          const double s = slip_level[i] * (p.coulomb + dip * weight) / p.stiffness;
          rate = speed[i] / s;
          decay = std::exp(-rate * duration[i]);
          z_inf = direction[i] * s;
        }
        carries[i] = {decay, z_inf, p.stiffness * z_inf + p.viscous * direction[i] * speed[i],
                      decay * (p.stiffness - p.micro_damping * rate)};
      }
      double z = z0;
      for (std::size_t r = 0; r + 1 < run_first.size(); ++r) {
        const Carry c = carries[run_motion[r]];
        const std::size_t last = run_first[r + 1] - 1;
        double y = z - c.z_inf;
        for (std::size_t k = run_first[r]; k <= last; ++k) {
          const double f = c.level_force + c.excess_force * y;
          const double e = force[k] - f;
          rss += e * e;
          y *= c.decay;
          const double next = c.z_inf + y;
          if (next == z && k < last) {
            // The state no longer changes in its last bit: samples k+1..last repeat force f (to
            // the force's rounding: what is left of the excess is below half a unit of z's last
            // place).
            const double d = f - run_mean[r];
            const double m = static_cast<double>(last - k);
            const double s1 = run_sum[last] - run_sum[k];
            const double s2 = run_square_sum[last] - run_square_sum[k];
            rss += std::max(0.0, s2 - 2.0 * d * s1 + m * d * d);
            break;
          }
          z = next;
        }
      }
    } else {
      buffer.resize(force.size());
      if (table) {
        LuGre<double> model(p);
        model.reset(z0);
        table->run(model, buffer.data());
      } else {
        run_exact(p, motions, z0, buffer.data());
      }
      for (std::size_t k = 0; k < force.size(); ++k) {
        const double e = force[k] - buffer[k];
        rss += e * e;
      }
    }
    return std::isfinite(rss) ? 100.0 * rss / sss : kHuge;
  }
  // x = (log theta, u), z0 = u times the rest deflection of those parameters.
  double percent(std::span<const double> v) const {
    const auto p = from_log(v.first(kP), shape);
    return percent(p, v[kP] * rest_deflection(p));
  }
};

// ---------------------------------------------------------------------------------------------
// Step 1: the data-driven start.

struct Segment {
  std::size_t a = 0, b = 0;  // reversal indices
  double dir = 1;            // sign of the travel
  double swing = 0;          // max g
  double breakaway = 0;      // max g over the first half of the travel
  std::size_t i95 = 0;       // first index with g >= 0.95 breakaway
  bool slides = false;
};

std::vector<Segment> segments_of(std::span<const double> x, std::span<const double> force,
                                 double resolution) {
  const double range = 2.0 * largest_travel(x);
  const double h = std::max(3.0 * resolution, 1e-4 * range);
  const auto turns = turning_points(x, h);
  std::vector<Segment> segs;
  for (std::size_t s = 0; s + 1 < turns.size(); ++s) {
    Segment g;
    g.a = turns[s];
    g.b = turns[s + 1];
    if (g.b <= g.a + 1) continue;
    g.dir = x[g.b] >= x[g.a] ? 1.0 : -1.0;
    const double travel = std::abs(x[g.b] - x[g.a]);
    if (travel <= h) continue;
    for (std::size_t t = g.a; t <= g.b; ++t) {
      const double rise = g.dir * (force[t] - force[g.a]);
      g.swing = std::max(g.swing, rise);
      if (std::abs(x[t] - x[g.a]) < 0.5 * travel) g.breakaway = std::max(g.breakaway, rise);
    }
    // The end of the transient is judged on the breakaway, not on the whole swing: when a stroke
    // slows down into its reversal, friction climbs the Stribeck curve again and can exceed the
    // plateau (and the breakaway peak, with frictional lag), which would put i95 at the very end
    // of the stroke and leave none of its samples sliding -- it did so for every 2 mm/s stroke
    // of data/estimation.csv.
    g.i95 = g.b;
    for (std::size_t t = g.a; t <= g.b; ++t)
      if (g.dir * (force[t] - force[g.a]) >= 0.95 * g.breakaway) {
        g.i95 = t;
        break;
      }
    // A plateau over the second half of the travel: the segment slides.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    std::size_t count = 0;
    for (std::size_t t = g.a; t <= g.b; ++t)
      if (std::abs(x[t] - x[g.a]) >= 0.5 * travel) {
        lo = std::min(lo, g.dir * force[t]);
        hi = std::max(hi, g.dir * force[t]);
        ++count;
      }
    g.slides = g.swing > 0.0 && count >= 2 && hi - lo <= 0.25 * g.swing;
    segs.push_back(g);
  }
  return segs;
}

// Least-squares slope and intercept of y on s.
std::pair<double, double> line_fit(const std::vector<double>& s, const std::vector<double>& y) {
  const double n = static_cast<double>(s.size());
  const double ms = std::accumulate(s.begin(), s.end(), 0.0) / n;
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    sxx += (s[i] - ms) * (s[i] - ms);
    sxy += (s[i] - ms) * (y[i] - my);
  }
  const double slope = sxx > 0.0 ? sxy / sxx : 0.0;
  return {slope, my - slope * ms};
}

// Least-squares line y = intercept + slope s with the statistics that say whether the slope is
// resolved: its standard error (residual scatter over the spread of s) and the spread of s.
struct LineStats {
  double slope = 0, intercept = 0;
  double slope_se = std::numeric_limits<double>::infinity();
  double spread = 0;  // standard deviation of s
};

LineStats line_stats(const std::vector<double>& s, const std::vector<double>& y) {
  LineStats f;
  const std::size_t n = s.size();
  if (n < 3) return f;
  const auto [slope, intercept] = line_fit(s, y);
  f.slope = slope;
  f.intercept = intercept;
  const double ms = std::accumulate(s.begin(), s.end(), 0.0) / static_cast<double>(n);
  double sxx = 0, rss = 0;
  for (std::size_t i = 0; i < n; ++i) {
    sxx += (s[i] - ms) * (s[i] - ms);
    const double e = y[i] - intercept - slope * s[i];
    rss += e * e;
  }
  f.spread = std::sqrt(sxx / static_cast<double>(n));
  if (sxx > 0.0) f.slope_se = std::sqrt(rss / static_cast<double>(n - 2) / sxx);
  return f;
}

void check_record(std::span<const double> time, std::span<const double> x,
                  std::span<const double> force, const char* who) {
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size(), who,
                 ": time, displacement and force lengths differ");
  FRICTION_CHECK(x.size() >= 20, who, ": ", x.size(), " samples are too few (at least 20)");
  for (std::size_t k = 0; k < x.size(); ++k) {
    FRICTION_CHECK(std::isfinite(time[k]) && std::isfinite(x[k]) && std::isfinite(force[k]), who,
                   ": sample ", k, " is not finite");
    if (k > 0)
      FRICTION_CHECK(time[k] > time[k - 1], who, ": time must increase strictly (sample ", k, ")");
  }
  double sss = 0;
  for (double f : force) sss += f * f;
  FRICTION_CHECK(sss > 0.0, who, ": the force is identically zero");
  FRICTION_CHECK(largest_travel(x) > 0.0, who, ": the displacement never changes");
}

// ---------------------------------------------------------------------------------------------
// Step 2: the global stage (NLopt).

struct SearchBox {
  std::vector<double> lower, upper;  // (log theta, u)
  std::vector<double> clamp(std::vector<double> v) const {
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::clamp(v[i], lower[i], upper[i]);
    return v;
  }
};

SearchBox search_box(const LgStart& st) {
  const auto& p = st.parameters;
  const double vmax = st.fastest_sliding_speed;
  SearchBox b;
  auto add = [&](double lo, double hi) {
    b.lower.push_back(std::log(lo));
    b.upper.push_back(std::log(hi));
  };
  add(p.stiffness / 10.0, p.stiffness * 10.0);
  add(p.micro_damping * 1e-3, p.micro_damping * 30.0);
  add(1e-4 * p.coulomb / vmax, std::max(3.0 * p.viscous, p.coulomb / vmax));
  add(p.coulomb / 3.0, p.coulomb * 3.0);
  add(p.static_force / 3.0, p.static_force * 3.0);
  add(std::min(st.slowest_sliding_speed / 10.0, p.stribeck_velocity / 3.0),
      std::max(10.0 * vmax, 3.0 * p.stribeck_velocity));
  add(0.3, 6.0);
  b.lower.push_back(-kStateBound);
  b.upper.push_back(kStateBound);
  return b;
}

struct Point {
  std::vector<double> v;  // (log theta, u)
  double percent = kHuge;
};

// BOBYQA (derivative-free, deterministic) from `start`: the best point it evaluated.
Point bobyqa(const Objective& obj, const SearchBox& box, Point start, int evaluations) {
  nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(kP + 1));
  opt.set_lower_bounds(box.lower);
  opt.set_upper_bounds(box.upper);
  opt.set_maxeval(evaluations);
  opt.set_ftol_rel(1e-9);
  std::vector<double> step(kP + 1);
  for (std::size_t i = 0; i <= kP; ++i) step[i] = 0.05 * (box.upper[i] - box.lower[i]);
  opt.set_initial_step(step);
  struct Ctx {
    const Objective* obj;
    Point best;
  } ctx{&obj, start};
  ctx.best.percent = obj.percent(start.v);
  opt.set_min_objective(
      [](const std::vector<double>& v, std::vector<double>&, void* data) -> double {
        auto* c = static_cast<Ctx*>(data);
        const double f = c->obj->percent(v);
        if (f < c->best.percent) c->best.percent = f, c->best.v = v;
        return f;
      },
      &ctx);
  std::vector<double> v = box.clamp(start.v);
  double f = 0;
  try {
    opt.optimize(v, f);
  } catch (const std::exception&) {
    // NLopt stops on round-off or a budget; the best point seen is kept in ctx.
  }
  return ctx.best;
}

// The global stage: controlled random search with local mutation (Price 1983; Kaelo & Ali 2006,
// "CRS2-LM").  A population of 10 (n + 1) points, the start and points uniform in the box; each
// trial reflects a random member through the centroid of the best and n - 1 other random members
// and replaces the worst member when it is better; when the reflection fails, a point on the line
// from it through the best, just beyond the best, is tried (the local mutation).  The algorithm of
// NLopt's GN_CRS2_LM, written here because NLopt draws its random numbers from a generator set by
// nlopt::srand, state shared by every search of the process (thread-local in Debian's build, but
// not by contract): this one is the call's own, seeded by LgOptions::seed, so concurrent
// identifications share nothing and each is reproducible.
Point controlled_random_search(const Objective& obj, const SearchBox& box, const Point& start,
                               int evaluations, unsigned seed) {
  const std::size_t n = box.lower.size();
  const std::size_t size = 10 * (n + 1);
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Point> pop;
  pop.reserve(size);
  Point first;
  first.v = box.clamp(start.v);
  first.percent = obj.percent(first.v);
  pop.push_back(first);
  int used = 1;
  while (pop.size() < size && used < evaluations) {
    Point p;
    p.v.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      p.v[i] = box.lower[i] + unit(gen) * (box.upper[i] - box.lower[i]);
    p.percent = obj.percent(p.v);
    ++used;
    pop.push_back(std::move(p));
  }
  const std::size_t m = pop.size();
  auto inside = [&](const std::vector<double>& v) {
    for (std::size_t i = 0; i < n; ++i)
      if (!(v[i] >= box.lower[i] && v[i] <= box.upper[i])) return false;
    return true;
  };
  auto evaluate = [&](const std::vector<double>& v) {
    if (!inside(v) || used >= evaluations) return kHuge;
    ++used;
    const double f = obj.percent(v);
    return std::isnan(f) ? kHuge : f;
  };
  std::uniform_int_distribution<std::size_t> member(0, m - 1);
  std::vector<std::size_t> pick(n + 1);
  std::vector<double> trial(n);
  // Reflections that land outside the box cost no evaluation: the attempts are capped as well.
  for (long attempt = 0; m > n + 1 && used < evaluations && attempt < 20L * evaluations;
       ++attempt) {
    std::size_t best = 0, worst = 0;
    for (std::size_t j = 1; j < m; ++j) {
      if (pop[j].percent < pop[best].percent) best = j;
      if (pop[j].percent > pop[worst].percent) worst = j;
    }
    pick[0] = best;
    for (std::size_t j = 1; j <= n; ++j) {
      std::size_t c;
      do {
        c = member(gen);
      } while (std::find(pick.begin(), pick.begin() + static_cast<std::ptrdiff_t>(j), c) !=
               pick.begin() + static_cast<std::ptrdiff_t>(j));
      pick[j] = c;
    }
    for (std::size_t i = 0; i < n; ++i) {
      double centroid = 0;
      for (std::size_t j = 0; j < n; ++j) centroid += pop[pick[j]].v[i];
      trial[i] = 2.0 * centroid / static_cast<double>(n) - pop[pick[n]].v[i];
    }
    double f = evaluate(trial);
    if (!(f < pop[worst].percent)) {
      for (std::size_t i = 0; i < n; ++i) {
        const double w = unit(gen);
        trial[i] = (1.0 + w) * pop[best].v[i] - w * trial[i];
      }
      f = evaluate(trial);
    }
    if (f < pop[worst].percent) {
      pop[worst].v = trial;
      pop[worst].percent = f;
    }
  }
  return *std::min_element(pop.begin(), pop.end(),
                           [](const Point& a, const Point& b) { return a.percent < b.percent; });
}

// ---------------------------------------------------------------------------------------------
// Step 4: covariance and warnings.

const std::array<const char*, kP> kSymbols{"sigma0", "sigma1", "sigma2", "Fc", "Fs", "vs", "mu"};
const std::array<const char*, kP> kUnits{"N/m", "N s/m", "N s/m", "N", "N", "m/s", "1"};

// Units as printed after a value in messages (nothing for the dimensionless exponent).
const std::array<const char*, kP> kUnitText{" N/m", " N s/m", " N s/m", " N", " N", " m/s", ""};
const char* unit_text(std::size_t j) {
  return kUnitText[j];
}

std::string pair_name(std::size_t a, std::size_t b) {
  return std::string(kLuGreParameterNames[a]) + " (" + kSymbols[a] + ") and " +
         kLuGreParameterNames[b] + " (" + kSymbols[b] + ")";
}

}  // namespace

// ---------------------------------------------------------------------------------------------

LgStart lugre_start(std::span<const double> time, std::span<const double> x,
                    std::span<const double> force, StribeckShape shape, double resolution) {
  check_record(time, x, force, "lugre_start");
  if (!(resolution > 0)) resolution = displacement_resolution(x);
  const std::size_t n = x.size();
  const auto motions = motions_of(time, x);
  const auto segs = segments_of(x, force, resolution);
  LgStart st;
  st.segments = segs.size();
  st.presliding.assign(n, false);

  std::vector<double> speed, level, travel;  // sliding samples: |v|, dir F, |dx|
  std::vector<double> presliding_speed;
  for (const auto& g : segs) {
    const double u95 = std::abs(x[g.i95] - x[g.a]);
    for (std::size_t t = g.a + 1; t <= g.b; ++t) {
      const double v = motions[t].velocity;
      if (!g.slides || t < g.i95) {
        st.presliding[t] = true;
        if (v != 0.0) presliding_speed.push_back(std::abs(v));
        continue;
      }
      if (std::abs(x[t] - x[g.a]) >= 1.5 * u95 && v * g.dir > 0.0) {
        speed.push_back(std::abs(v));
        level.push_back(g.dir * force[t]);
        travel.push_back(std::abs(motions[t].dx));
      }
    }
    st.sliding_segments += g.slides;
  }
  st.sliding_samples = speed.size();
  FRICTION_CHECK(st.sliding_segments > 0 && speed.size() >= 10, "lugre_start: the record ",
                 st.sliding_segments == 0 ? "never slides" : "hardly slides", " (",
                 st.sliding_segments, " of ", segs.size(),
                 " segments between reversals reach a force plateau, ", speed.size(),
                 " sliding samples): Fc, Fs, vs, mu and sigma2 cannot be identified from "
                 "presliding alone; excite sliding (strokes longer than the presliding travel)");
  // Percentiles weighted by the travel of each sample: a fast stroke has few samples, and by
  // count the 95th percentile missed the 5 mm/s strokes of data/estimation.csv (5 % of the
  // sliding samples, 20 % of the sliding travel).
  st.slowest_sliding_speed = weighted_quantile(speed, travel, 0.05);
  st.fastest_sliding_speed = weighted_quantile(speed, travel, 0.95);
  FRICTION_CHECK(st.fastest_sliding_speed > 0.0, "lugre_start: no sliding speed");
  {
    const double level_median = statistics::upper_median(level);
    FRICTION_CHECK(level_median > 0.0, "lugre_start: the median sliding force along the motion, ",
                   level_median, " N over ", speed.size(), " sliding samples at ",
                   st.slowest_sliding_speed, " to ", st.fastest_sliding_speed,
                   " m/s, is not positive: the force pushes the motion instead of resisting it. Is "
                   "the force in the model's sign convention (F v > 0 while sliding)? A force "
                   "measured on the moving body has the opposite sign (read_record's force sign "
                   "`auto` flips it)");
  }
  // Velocity noise of the backward difference: one quantum q / Ts of velocity (between the
  // q / (sqrt(6) Ts) of quantisation and the sqrt(2) q / Ts of white noise of deviation q).
  std::vector<double> dt(n - 1);
  for (std::size_t k = 1; k < n; ++k) dt[k - 1] = time[k] - time[k - 1];
  st.velocity_noise = resolution / statistics::upper_median(dt);

  auto& p = st.parameters;
  p.shape = shape;
  // Fc and sigma2 from the fastest third (by travel) of the sliding samples.
  {
    const double q67 = weighted_quantile(speed, travel, 2.0 / 3.0);
    std::vector<double> s, y;
    for (std::size_t i = 0; i < speed.size(); ++i)
      if (speed[i] >= q67) s.push_back(speed[i]), y.push_back(level[i]);
    const LineStats line = line_stats(s, y);
    // A slope needs speeds that differ by more than their noise: at one commanded speed the
    // speeds of the fit differ only by quantisation (or by rounding), sxx is ~0, and the line
    // extrapolates anywhere (the tribometer record gave Fc = -1.2e9 N).
    st.one_speed = !(line.spread > 2.0 * st.velocity_noise);
    // The slope is used when it is resolved (more than twice its standard error, which weighs
    // the spread of the speeds against the scatter of the levels) and the line meets v = 0 at a
    // positive level.  Otherwise (one speed, the Stribeck dip not yet over, or viscous friction
    // lost in the noise) Fc is the median level and sigma2 starts small and positive.
    st.viscous_from_slope = !st.one_speed && line.slope > 2.0 * line.slope_se &&
                            std::isfinite(line.slope) && line.intercept > 0.0;
    if (st.viscous_from_slope) {
      std::vector<double> base(s.size());
      for (std::size_t i = 0; i < s.size(); ++i) base[i] = y[i] - line.slope * s[i];
      p.coulomb = statistics::upper_median(base);
      p.viscous = line.slope;
    }
    if (!st.viscous_from_slope || !(p.coulomb > 0.0)) {
      st.viscous_from_slope = false;
      p.coulomb = statistics::upper_median(y);
      p.viscous = 0.01 * p.coulomb / st.fastest_sliding_speed;
    }
    FRICTION_CHECK(p.coulomb > 0.0,
                   "lugre_start: the median force of the fastest sliding samples, ", p.coulomb,
                   " N, is not positive");
  }
  if (st.one_speed || st.fastest_sliding_speed < 3.0 * st.slowest_sliding_speed) {
    std::ostringstream w;
    w << "the record slides at nearly one speed (" << st.slowest_sliding_speed << " to "
      << st.fastest_sliding_speed << " m/s";
    if (st.one_speed)
      w << "; the fastest sliding speeds vary by no more than their noise, " << st.velocity_noise
        << " m/s";
    w << "): viscous friction (sigma2), Fs, vs and mu cannot be separated from Fc at one speed";
    if (st.one_speed) w << "; the start takes Fc as the median sliding level and a small sigma2";
    w << "; a record sliding at several speeds would separate them";
    st.warnings.push_back(w.str());
  }
  // Fs: slowest sliding level, or the breakaway peaks.
  {
    const double q10 = quantile(speed, 0.1);
    std::vector<double> low;
    for (std::size_t i = 0; i < speed.size(); ++i)
      if (speed[i] <= q10) low.push_back(level[i] - p.viscous * speed[i]);
    std::vector<double> peaks;
    for (const auto& g : segs) {
      if (!g.slides) continue;
      double peak = -std::numeric_limits<double>::infinity();
      for (std::size_t t = g.a + 1; t <= g.b; ++t)
        peak = std::max(peak, g.dir * force[t] - p.viscous * std::abs(motions[t].velocity));
      peaks.push_back(peak);
    }
    p.static_force = std::max(
        {statistics::upper_median(low), statistics::upper_median(peaks), 1.01 * p.coulomb});
  }
  // Fs and vs: the static curve Fc + (Fs - Fc) w(v; vs, mu = 2) fitted to the sliding levels.
  {
    const double observed = p.static_force;
    double best_cost = std::numeric_limits<double>::infinity();
    LuGreParameters<double> q = p;
    q.stribeck_exponent = 2.0;
    constexpr int kGrid = 61;
    const double lo = std::log(st.slowest_sliding_speed / 10.0);
    const double hi = std::log(3.0 * st.fastest_sliding_speed);
    std::vector<double> w(speed.size());
    for (int i = 0; i < kGrid; ++i) {
      q.stribeck_velocity = std::exp(lo + (hi - lo) * i / (kGrid - 1));
      double ww = 0, wl = 0;
      for (std::size_t k = 0; k < speed.size(); ++k) {
        w[k] = stribeck_weight(q, speed[k]);
        ww += w[k] * w[k];
        wl += w[k] * (level[k] - p.viscous * speed[k] - p.coulomb);
      }
      const double dip =
          std::clamp(ww > 0.0 ? wl / ww : 0.0, observed - p.coulomb, 2.0 * observed - p.coulomb);
      double cost = 0;
      for (std::size_t k = 0; k < speed.size(); ++k) {
        const double e = level[k] - p.viscous * speed[k] - p.coulomb - dip * w[k];
        cost += e * e;
      }
      if (cost < best_cost) {
        best_cost = cost;
        p.stribeck_velocity = q.stribeck_velocity;
        p.static_force = p.coulomb + dip;
      }
    }
  }
  // sigma0 and sigma1 from the rise after reversals from sliding: pooled regression of dir F on
  // the travel u and the speed |v| (each segment with its own intercept) over the travel until g
  // covers f = 30 % of S.  Leaving steady sliding the bristles go from -s to +s with
  // dz/dx = 1 + |z|/s, so both coefficients are -2 f / ln(1 - f) = 1.68 times sigma0 and sigma1.
  {
    constexpr double kF = 0.3;
    const double factor = -2.0 * kF / std::log(1.0 - kF);
    Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    std::size_t used = 0;
    std::vector<double> slopes;  // single-regressor chord slopes of every segment (fallback)
    for (std::size_t s = 0; s < segs.size(); ++s) {
      const auto& g = segs[s];
      if (g.swing <= 0.0) continue;
      std::vector<double> u, v, y;
      for (std::size_t t = g.a; t <= g.b; ++t) {
        if (t > g.a && g.dir * (force[t] - force[g.a]) >= kF * g.swing) break;
        u.push_back(g.dir * (x[t] - x[g.a]));
        v.push_back(t > g.a ? std::abs(motions[t].velocity) : 0.0);
        y.push_back(g.dir * force[t]);
      }
      if (u.size() < 3) continue;
      const double slope = line_fit(u, y).first;
      if (slope > 0.0) slopes.push_back(slope);
      if (!(s > 0 && segs[s - 1].slides && segs[s - 1].b == g.a)) continue;
      const double nu = static_cast<double>(u.size());
      const double mu_ = std::accumulate(u.begin(), u.end(), 0.0) / nu;
      const double mv = std::accumulate(v.begin(), v.end(), 0.0) / nu;
      const double my = std::accumulate(y.begin(), y.end(), 0.0) / nu;
      for (std::size_t i = 0; i < u.size(); ++i) {
        const Eigen::Vector2d r(u[i] - mu_, v[i] - mv);
        a += r * r.transpose();
        b += r * (y[i] - my);
      }
      used += u.size();
    }
    bool done = false;
    if (used >= 6 && a.determinant() > 1e-12 * a(0, 0) * a(1, 1)) {
      const Eigen::Vector2d c = a.ldlt().solve(b);
      if (c(0) > 0.0) {
        p.stiffness = c(0) / factor;
        p.micro_damping = c(1) > 0.0 ? c(1) / factor : 0.0;
        st.sigma0_from_sliding_reversals = done = true;
      }
    }
    if (!done) {
      if (!slopes.empty()) {
        p.stiffness = statistics::upper_median(slopes);
      } else {
        // No resolved presliding: the exponential approach covers 95 % of 2 Fs in 3 s(0).
        const double travel = travel_at_force_fraction(x, force, 0.95);
        p.stiffness = 3.0 * p.static_force / std::max(travel, resolution);
      }
    }
  }
  // sigma1 without the regression: 10 % of Fs at the typical presliding speed.
  st.presliding_speed = presliding_speed.empty() ? st.slowest_sliding_speed
                                                 : statistics::upper_median(presliding_speed);
  if (!(p.micro_damping > 0.0))
    p.micro_damping = 0.1 * p.static_force / std::max(st.presliding_speed, 1e-300);
  p.stribeck_exponent = 2.0;
  p.validate();
  return st;
}

// ---------------------------------------------------------------------------------------------

LgCostFunction::LgCostFunction(std::span<const double> time, std::span<const double> x,
                               std::span<const double> force, double scale, double z_ref,
                               StribeckShape shape, LgJacobian jacobian,
                               const CvodesOptions& cvodes)
    : time_(time),
      x_(x),
      force_(force),
      scale_(scale),
      z_ref_(z_ref),
      shape_(shape),
      jacobian_(jacobian),
      cvodes_(cvodes) {
  FRICTION_CHECK(time.size() == x.size() && x.size() == force.size() && !x.empty(),
                 "LgCostFunction: lengths differ");
  motions_ = motions_of(time, x);
  FRICTION_CHECK(scale > 0.0 && z_ref > 0.0, "LgCostFunction: scale and z_ref must be > 0");
  cvodes_.sensitivities = true;
  cvodes_.log_parameters = true;
  set_num_residuals(static_cast<int>(x.size()));
  mutable_parameter_block_sizes()->push_back(static_cast<int>(kP));
  mutable_parameter_block_sizes()->push_back(1);
}

bool LgCostFunction::Evaluate(double const* const* parameters, double* residuals,
                              double** jacobians) const {
  const std::size_t n = x_.size();
  const auto p = from_log({parameters[0], kP}, shape_);
  if (!finite_parameters(p) || !std::isfinite(parameters[1][0])) return false;
  const double z0 = parameters[1][0] * z_ref_;
  const auto& motions = motions_;
  try {
    const bool want_j = jacobians && (jacobians[0] || jacobians[1]);
    if (want_j && jacobian_ == LgJacobian::Cvodes && memo_.parameters.size() == kP + 1 &&
        std::equal(parameters[0], parameters[0] + kP, memo_.parameters.begin()) &&
        parameters[1][0] == memo_.parameters[kP]) {
      std::copy(memo_.residuals.begin(), memo_.residuals.end(), residuals);
      if (jacobians[0])
        std::copy(memo_.jacobian_theta.begin(), memo_.jacobian_theta.end(), jacobians[0]);
      if (jacobians[1])
        std::copy(memo_.jacobian_state.begin(), memo_.jacobian_state.end(), jacobians[1]);
      return true;
    }
    if (want_j) ++jacobian_evaluations_;
    if (want_j && jacobian_ == LgJacobian::ExactStep) {
      using Jet = ceres::Jet<double, kP + 1>;
      std::array<Jet, kP> theta;
      for (std::size_t j = 0; j < kP; ++j)
        theta[j] = exp(Jet(parameters[0][j], static_cast<int>(j)));
      const auto pj = LuGreParameters<Jet>::from_array(theta, shape_);
      std::vector<Jet> f(n);
      run_exact(pj, motions, Jet(parameters[1][0], static_cast<int>(kP)) * z_ref_, f.data());
      for (std::size_t k = 0; k < n; ++k) {
        residuals[k] = (force_[k] - f[k].a) / scale_;
        if (jacobians[0])
          for (std::size_t j = 0; j < kP; ++j) jacobians[0][kP * k + j] = -f[k].v[j] / scale_;
        if (jacobians[1]) jacobians[1][k] = -f[k].v[kP] / scale_;
      }
    } else {
      std::vector<double> f(n);
      run_exact(p, motions, z0, f.data());
      for (std::size_t k = 0; k < n; ++k) residuals[k] = (force_[k] - f[k]) / scale_;
      if (want_j) {
        const auto sim = simulate_lugre_cvodes(p, time_, x_, cvodes_, z0);
        if (jacobians[0])
          Eigen::Map<RowMajor>(jacobians[0], static_cast<Eigen::Index>(n), kP) =
              -Eigen::Map<const RowMajor>(sim.jacobian.data(), static_cast<Eigen::Index>(n), kP) /
              scale_;
        if (jacobians[1])
          for (std::size_t k = 0; k < n; ++k)
            jacobians[1][k] = -sim.initial_state_derivative[k] * z_ref_ / scale_;
        memo_.parameters.assign(parameters[0], parameters[0] + kP);
        memo_.parameters.push_back(parameters[1][0]);
        memo_.residuals.assign(residuals, residuals + n);
        memo_.jacobian_theta.clear();
        memo_.jacobian_state.clear();
        if (jacobians[0]) memo_.jacobian_theta.assign(jacobians[0], jacobians[0] + n * kP);
        if (jacobians[1]) memo_.jacobian_state.assign(jacobians[1], jacobians[1] + n);
        // Only a complete record answers a later request (which may want either block).
        if (!jacobians[0] || !jacobians[1]) memo_.parameters.clear();
      }
    }
  } catch (const Error&) {
    return false;  // an unusable trial point: Ceres shrinks its trust region
  }
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isfinite(residuals[k])) {
      memo_.parameters.clear();
      return false;
    }
  return true;
}

// ---------------------------------------------------------------------------------------------

double estimate_lugre_initial_state(const LuGreParameters<double>& parameters,
                                    std::span<const double> time, std::span<const double> x,
                                    std::span<const double> force) {
  parameters.validate();
  check_record(time, x, force, "estimate_lugre_initial_state");
  // The state equation (eq. 1) and the force (eq. 2) are affine in z, and so is the exact step
  // over each interval: every simulated force is a_k + b_k z0.  One run with a one-direction Jet
  // from z0 = 0 gives a_k and b_k, and the least-squares z0 follows in closed form.  The cost is
  // a parabola in z0, so the bounded minimum is the unbounded one clamped.  (A scan and
  // Gauss-Newton did the same in 41 scan runs, two Jet runs and 21 exact runs: Gauss-Newton's
  // second step was always at rounding, and its line search halved 20 times in vain.)
  using Jet = ceres::Jet<double, 1>;
  std::vector<Jet> f(x.size());
  run_exact(parameters.cast<Jet>(), motions_of(time, x), Jet(0.0, 0), f.data());
  double br = 0, bb = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    br += f[k].v[0] * (force[k] - f[k].a);
    bb += f[k].v[0] * f[k].v[0];
  }
  const double z = br / bb;
  FRICTION_CHECK(bb > 0.0 && std::isfinite(z), "estimate_lugre_initial_state: the simulated "
                 "force does not depend on the initial state (sum of squared sensitivities ",
                 bb, ")");
  const double bound = kStateBound * rest_deflection(parameters);
  return std::clamp(z, -bound, bound);
}

LuGreFreeRun free_run_lugre(const LuGreParameters<double>& parameters, std::span<const double> time,
                            std::span<const double> x, std::span<const double> force) {
  LuGreFreeRun run;
  run.initial_state = estimate_lugre_initial_state(parameters, time, x, force);
  run.simulated.resize(x.size());
  run_exact(parameters, motions_of(time, x), run.initial_state, run.simulated.data());
  run.errors = compute_errors(force, run.simulated);
  return run;
}

// ---------------------------------------------------------------------------------------------

LgResult identify_lugre(std::span<const double> time, std::span<const double> x,
                        std::span<const double> force, const LgOptions& o) {
  const detail::SubnormalsFlushed subnormals_flushed;  // subnormals.hpp
  const auto clock_start = std::chrono::steady_clock::now();
  auto lap_t = clock_start;
  auto lap = [&lap_t](double& into) {
    const auto now = std::chrono::steady_clock::now();
    into += std::chrono::duration<double>(now - lap_t).count();
    lap_t = now;
  };
  check_record(time, x, force, "identify_lugre");
  FRICTION_CHECK(o.max_iterations >= 0 && o.global_evaluations >= 0 && o.polish_evaluations >= 0,
                 "identify_lugre: negative budgets");
  LgResult result;
  IdentificationReport& rep = result.report;
  const std::size_t n = x.size();
  const double nd = static_cast<double>(n);

  const double resolution =
      o.displacement_resolution > 0 ? o.displacement_resolution : displacement_resolution(x);
  result.start = lugre_start(time, x, force, o.shape, resolution);
  const LgStart& st = result.start;
  rep.displacement_resolution = resolution;
  rep.largest_travel = largest_travel(x);
  rep.presliding_travel = travel_at_force_fraction(x, force, 0.95);

  Objective obj;
  obj.force = force;
  obj.motions = motions_of(time, x);
  if (o.memoise_steps) obj.index_motions();
  result.timings.global_transitions = obj.table           ? "tabulated"
                                      : obj.which.empty() ? "exact"
                                                          : "shared";
  obj.shape = o.shape;
  for (double f : force) obj.sss += f * f;
  const double scale = std::sqrt(obj.sss / nd);

  const SearchBox box = search_box(st);
  auto to_point = [&](const LuGreParameters<double>& p, double u) {
    Point pt;
    for (double t : p.to_array()) pt.v.push_back(std::log(t));
    pt.v.push_back(u);
    pt.v = box.clamp(pt.v);
    pt.percent = obj.percent(pt.v);
    return pt;
  };
  auto point_log = [&](const Point& pt) {
    const auto p = from_log({pt.v.data(), kP}, o.shape);
    std::vector<double> out;
    for (double t : p.to_array()) out.push_back(t);
    out.push_back(pt.v[kP] * rest_deflection(p));
    return out;
  };
  std::vector<double> minima;
  auto log_start = [&](const std::string& kind, const Point& from, const Point& to) {
    StartLog s;
    s.operators = 1;
    s.kind = kind;
    s.start_thresholds = point_log(from);
    s.final_thresholds = point_log(to);
    s.start_percent = from.percent;
    s.final_percent = to.percent;
    s.distinct = std::none_of(minima.begin(), minima.end(), [&](double m) {
      return std::abs(m - to.percent) <= 0.01 * std::max(m, to.percent);
    });
    if (s.distinct) minima.push_back(to.percent);
    rep.starts.push_back(std::move(s));
  };

  // Start: the data-driven parameters with the initial state that suits them.
  const double z_start = estimate_lugre_initial_state(st.parameters, time, x, force);
  Point start = to_point(st.parameters, z_start / rest_deflection(st.parameters));
  Point best = start;
  int local_searches = 0;
  lap(result.timings.start);
  if (o.global_stage) {
    const Point polished = bobyqa(obj, box, start, o.polish_evaluations);
    ++local_searches;
    log_start("data-driven+bobyqa", start, polished);
    best = polished;
    const int budget = o.global_evaluations > 0 ? o.global_evaluations : 1500;
    const Point global = controlled_random_search(obj, box, start, budget, o.seed);
    const Point global_polished = bobyqa(obj, box, global, o.polish_evaluations);
    ++local_searches;
    lap(result.timings.global);
    log_start("crs2-lm+bobyqa", start, global_polished);
    if (global_polished.percent < best.percent) best = global_polished;
  }

  // Local stage: Ceres with the exact step's (or CVODES') Jacobian.
  const auto p_best = from_log({best.v.data(), kP}, o.shape);
  const double z_ref = rest_deflection(p_best);
  std::vector<double> log_theta(best.v.begin(), best.v.begin() + kP);
  double u = best.v[kP];
  ceres::Solver::Summary summary;
  LgCostFunction::Memo final_jacobian;  // Ceres' last Jacobian, at its final point
  {
    ceres::Problem problem;
    auto* cost = new LgCostFunction(time, x, force, scale, z_ref, o.shape, o.jacobian, o.cvodes);
    problem.AddResidualBlock(cost, nullptr, log_theta.data(), &u);
    for (std::size_t j = 0; j < kP; ++j) {
      problem.SetParameterLowerBound(log_theta.data(), static_cast<int>(j), box.lower[j]);
      problem.SetParameterUpperBound(log_theta.data(), static_cast<int>(j), box.upper[j]);
    }
    problem.SetParameterLowerBound(&u, 0, -kStateBound);
    problem.SetParameterUpperBound(&u, 0, kStateBound);
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = o.max_iterations;
    so.function_tolerance = detail::resolved_function_tolerance(n);
    so.gradient_tolerance = 1e-12;
    so.parameter_tolerance = 1e-9;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    // No projected line search at the bounds: each of its steps would need a full Jacobian
    // (a CVODES run with sensitivities); measured, it made 100+ Jacobians in 8 iterations.
    so.max_num_line_search_step_size_iterations = 0;
    ceres::Solve(so, &problem, &summary);
    ++local_searches;
    result.timings.jacobian_evaluations = cost->jacobian_evaluations();
    final_jacobian = cost->take_memo();
    lap(result.timings.local);
  }
  // The check at the optimum: CVODES' forward sensitivities against the exact step's Jacobian
  // (the same model: the exact step is exact for the piecewise-constant velocity CVODES
  // integrates).  Its Jacobian is then the covariance's.
  double cvodes_difference = -1;
  if (o.cvodes_check && o.jacobian != LgJacobian::Cvodes) {
    RowMajor jc(static_cast<Eigen::Index>(n), kP), je(static_cast<Eigen::Index>(n), kP);
    std::vector<double> r(n), sc(n), se(n);
    const double* blocks[2] = {log_theta.data(), &u};
    double* jcs[2] = {jc.data(), sc.data()};
    double* jes[2] = {je.data(), se.data()};
    LgCostFunction cv(time, x, force, scale, z_ref, o.shape, LgJacobian::Cvodes, o.cvodes);
    const LgCostFunction ex(time, x, force, scale, z_ref, o.shape, LgJacobian::ExactStep, o.cvodes);
    if (cv.Evaluate(blocks, r.data(), jcs) && ex.Evaluate(blocks, r.data(), jes)) {
      cvodes_difference = (jc - je).norm() / std::max(je.norm(), 1e-300);
      final_jacobian = cv.take_memo();
      ++result.timings.jacobian_evaluations;
    } else {
      rep.warnings.push_back(
          "CVODES could not integrate the sensitivities at the optimum: the covariance uses the "
          "exact step's Jacobian");
    }
    lap(result.timings.local);
  }
  result.parameters = from_log(log_theta, o.shape);
  {
    Point local;
    local.v = log_theta;
    local.v.push_back(u * z_ref / rest_deflection(result.parameters));
    local.percent = 100.0 * 2.0 * summary.final_cost / nd;
    Point from = best;
    from.percent = 100.0 * 2.0 * summary.initial_cost / nd;
    log_start("ceres", from, local);
  }

  // Errors of the free run from the estimated initial state (the routine validation uses).
  const auto& p = result.parameters;
  const LuGreFreeRun run = free_run_lugre(p, time, x, force);
  result.initial_state = run.initial_state;
  rep.initial_deflections = {run.initial_state};
  rep.estimation_simulated = run.simulated;
  rep.estimation = run.errors;
  rep.noise_sigma = estimate_white_noise_sigma(force);
  rep.noise_floor_percent = noise_floor_rss_sss_percent(force, rep.noise_sigma);

  auto& conv = rep.convergence;
  conv.converged = summary.termination_type == ceres::CONVERGENCE;
  conv.iterations = static_cast<int>(summary.iterations.size());
  conv.local_searches = local_searches;
  conv.initial_cost = 100.0 * 2.0 * summary.initial_cost / nd;
  conv.final_cost = rep.estimation.rss_sss_percent;
  conv.message = summary.message;
  if (cvodes_difference >= 0) {
    std::ostringstream m;
    m << "; at the optimum CVODES' sensitivities and the exact step's Jacobian differ by "
      << cvodes_difference << " (relative, Frobenius)";
    conv.message += m.str();
    if (cvodes_difference > 1e-2) {
      std::ostringstream w;
      w << "CVODES' sensitivities at the optimum differ from the exact step's Jacobian by "
        << cvodes_difference << " (relative): the standard errors are uncertain";
      rep.warnings.push_back(w.str());
    }
  }
  if (!conv.converged)
    rep.warnings.push_back("the local search (Ceres) did not report convergence: " +
                           summary.message);

  SelectionRow row;
  row.operators = 1;
  row.parameters = kP;
  row.rss = rep.estimation.rss;
  row.rss_sss_percent = rep.estimation.rss_sss_percent;
  row.criterion = bayesian_information_criterion(row.rss, n, kP);
  row.selected = true;
  rep.selection.push_back(row);

  // Parameters, uncertainty, identifiability.
  const auto theta = p.to_array();
  for (std::size_t j = 0; j < kP; ++j)
    rep.parameters.push_back(
        {kLuGreParameterNames[j], kUnits[j], theta[j], 0.0, theta[j], theta[j]});
  rep.correlation = Eigen::MatrixXd::Identity(kP, kP);
  for (std::size_t j = 0; j < kP; ++j) {
    const double lt = std::log(theta[j]);
    const double width = box.upper[j] - box.lower[j];
    if (lt <= box.lower[j] + 1e-3 * width || lt >= box.upper[j] - 1e-3 * width) {
      std::ostringstream w;
      w << kLuGreParameterNames[j] << " (" << kSymbols[j] << ") = " << theta[j] << unit_text(j)
        << " is at its search bound [" << std::exp(box.lower[j]) << ", " << std::exp(box.upper[j])
        << "]";
      rep.warnings.push_back(w.str());
    }
  }
  if (o.covariance) {
    std::vector<double> lt(theta.size());
    for (std::size_t j = 0; j < kP; ++j) lt[j] = std::log(theta[j]);
    double u_final = run.initial_state / rest_deflection(p);
    const double zr = rest_deflection(p);
    // The exact Jacobian (autodiff through the exact step) for the rank diagnosis.
    Eigen::MatrixXd jtj(kP, kP);
    {
      RowMajor j(static_cast<Eigen::Index>(n), kP);
      std::vector<double> r(n);
      const double* blocks[2] = {lt.data(), &u_final};
      double* jacs[2] = {j.data(), nullptr};
      const LgCostFunction exact(time, x, force, scale, zr, o.shape, LgJacobian::ExactStep,
                                 o.cvodes);
      if (exact.Evaluate(blocks, r.data(), jacs))
        jtj = j.transpose() * j;
      else
        jtj.setZero();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(jtj);
    const Eigen::VectorXd lambda = eig.eigenvalues();  // ascending
    const double lmax = lambda(kP - 1);
    const double rcond = lmax > 0.0 ? std::max(0.0, lambda(0)) / lmax : 0.0;
    std::vector<bool> null_parameter(kP, false);
    auto weakest = [&](Eigen::Index k) {
      std::string names;
      for (std::size_t j = 0; j < kP; ++j)
        if (std::abs(eig.eigenvectors()(static_cast<Eigen::Index>(j), k)) > 0.3)
          names += (names.empty() ? "" : ", ") + std::string(kSymbols[j]);
      return names;
    };
    for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(kP); ++k)
      if (!(lmax > 0.0) || lambda(k) < 1e-14 * lmax)
        for (std::size_t j = 0; j < kP; ++j)
          if (std::abs(eig.eigenvectors()(static_cast<Eigen::Index>(j), k)) > 0.3)
            null_parameter[j] = true;
    if (rcond < 1e-10) {
      std::ostringstream w;
      w << "the problem is near-singular (reciprocal condition number of J^T J " << rcond
        << "): the weakest direction involves " << weakest(0);
      rep.warnings.push_back(w.str());
    }

    // At the fit's own point (Ceres' parameters and initial state; the reported errors use the
    // free run's own estimate of the state, which moves the Jacobian by little: standard errors
    // within 1e-5 on data/ and the tribometer), where Ceres' last Jacobian already is.
    std::vector<double> lt_fit = log_theta;
    double u_fit = u;
    auto* fit_cost = new LgCostFunction(
        time, x, force, scale, z_ref, o.shape,
        o.cvodes_check && cvodes_difference >= 0 ? LgJacobian::Cvodes : o.jacobian, o.cvodes);
    fit_cost->reuse(std::move(final_jacobian));
    ceres::Problem problem;
    problem.AddResidualBlock(fit_cost, nullptr, lt_fit.data(), &u_fit);
    problem.SetParameterBlockConstant(&u_fit);
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;  // pseudo-inverse: drop directions below the tolerance
    co.min_reciprocal_condition_number = 1e-14;
    co.num_threads = 1;
    ceres::Covariance cov(co);
    Eigen::Matrix<double, kP, kP, Eigen::RowMajor> c;
    bool ok = false;
    try {
      const std::vector<std::pair<const double*, const double*>> blocks{
          {lt_fit.data(), lt_fit.data()}};
      ok = cov.Compute(blocks, &problem) &&
           cov.GetCovarianceBlock(lt_fit.data(), lt_fit.data(), c.data());
    } catch (const std::exception&) {
      ok = false;
    }
    const double sigma2 = rep.estimation.rss / (scale * scale) / std::max(1.0, nd - (kP + 1));
    const bool usable = ok && c.allFinite();
    Eigen::MatrixXd cs = c;
    if (usable) cs *= sigma2;
    // The parameters are fitted through their logarithms in a box: log-normal intervals clipped
    // to the box; a parameter in the null space of J^T J has no standard error.
    std::vector<CovarianceParameter> cp;
    for (std::size_t a = 0; a < kP; ++a)
      cp.push_back({rep.parameters[a].name, rep.parameters[a].unit, rep.parameters[a].value,
                    Parametrisation::log, 1.0,
                    null_parameter[a] ? std::ptrdiff_t{-1} : static_cast<std::ptrdiff_t>(a), false,
                    std::exp(box.lower[a]), std::exp(box.upper[a])});
    CovarianceOptions report_options;
    report_options.clip_to_limits = true;
    const CovarianceReport cr = covariance_report(usable ? &cs : nullptr, cp, report_options);
    if (usable) {
      cr.apply(rep.parameters);
      rep.correlation = cr.correlation;
    }
    std::string unavailable;
    for (const IdentifiabilityWarning& w : cr.warnings) {
      const std::size_t a = w.parameter;
      if (w.issue == IdentifiabilityIssue::no_standard_error) {
        unavailable += (unavailable.empty() ? "" : ", ") + std::string(kSymbols[a]);
      } else if (w.issue == IdentifiabilityIssue::wide_interval) {
        const ParameterEstimate& est = rep.parameters[a];
        std::ostringstream t;
        t << est.name << " (" << kSymbols[a] << "): 95 % interval [" << est.lower95 << ", "
          << est.upper95 << "]" << unit_text(a)
          << (cr.parameters[a].clipped ? " (clipped to the search bounds)" : "")
          << " spans more than an order of magnitude (poorly identified)";
        rep.warnings.push_back(t.str());
      }
    }
    if (usable) {
      if (!unavailable.empty())
        rep.warnings.push_back(
            "the parameter covariance is rank-deficient; no standard error for " + unavailable +
            " (not identifiable from this record)");
      // The trade-offs known for LuGre on records of modest speed (methods.md 8), then any pair.
      const std::array<std::pair<std::size_t, std::size_t>, 2> known{{{4, 5}, {6, 2}}};
      for (const auto& [a, b] : known) {
        const double r =
            rep.correlation(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
        if (std::abs(r) > 0.9) {
          std::ostringstream w;
          w << pair_name(a, b) << " trade off (correlation " << r
            << "): at the sliding speeds of this record they are not separately identifiable; "
               "a record sliding over a wider range of speeds would separate them";
          rep.warnings.push_back(w.str());
        }
      }
      for (std::size_t a = 0; a < kP; ++a)
        for (std::size_t b = a + 1; b < kP; ++b) {
          if ((a == 4 && b == 5) || (a == 2 && b == 6)) continue;
          const double r =
              rep.correlation(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
          if (std::abs(r) > 0.95) {
            std::ostringstream w;
            w << pair_name(a, b) << " are correlated (" << r << ")";
            rep.warnings.push_back(w.str());
          }
        }
    } else {
      rep.warnings.push_back(
          "the parameter covariance could not be computed (some parameters are not identifiable "
          "from this record); standard errors are not available");
    }
  }

  // What the record can tell.
  if (st.sliding_segments < 2)
    rep.warnings.push_back(
        "only one segment between reversals slides: the sliding parameters "
        "rest on a single stroke");
  rep.warnings.insert(rep.warnings.end(), st.warnings.begin(), st.warnings.end());
  if (rep.noise_floor_percent > 0.0 &&
      rep.estimation.rss_sss_percent > 3.0 * rep.noise_floor_percent) {
    double pre = 0;
    for (std::size_t k = 0; k < n; ++k)
      if (st.presliding[k]) {
        const double e = force[k] - run.simulated[k];
        pre += e * e;
      }
    std::ostringstream w;
    w.precision(3);
    w << "the estimation error " << rep.estimation.rss_sss_percent << " % is "
      << rep.estimation.rss_sss_percent / rep.noise_floor_percent << " times the noise floor "
      << rep.noise_floor_percent << " %, " << 100.0 * pre / std::max(rep.estimation.rss, 1e-300)
      << " % of it in presliding: a single-state LuGre cannot reproduce multi-element presliding "
         "hysteresis (nonlocal memory); a Maxwell Slip model may fit this record better";
    rep.warnings.push_back(w.str());
  }
  lap(result.timings.report);
  rep.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

}  // namespace friction
