// Velocity and acceleration at the sample instants (see sample_derivatives.hpp).
#include "friction/sample_derivatives.hpp"

#include <Eigen/Core>
#include <Eigen/Dense>
#include <Eigen/LU>
#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <mutex>
#include <numbers>
#include <optional>
#include <vector>

#include "friction/error.hpp"
#include "friction/signals.hpp"
#include "sample_statistics.hpp"

namespace friction {

namespace {

void check_record(std::span<const double> time, std::span<const double> x, std::size_t minimum) {
  FRICTION_CHECK(time.size() == x.size(),
                 "sample derivatives: time and displacement differ in length");
  FRICTION_CHECK(x.size() >= minimum, "sample derivatives: ", x.size(), " samples, at least ",
                 minimum, " needed");
  for (std::size_t k = 1; k < time.size(); ++k)
    FRICTION_CHECK(time[k] > time[k - 1],
                   "sample derivatives: time must increase strictly (sample ", k, ")");
}

// One pass of local quadratic fits with half width m; writes the fitted value at every sample (the
// smooth estimate of the encoder model below; the derivatives come from apply_local_derivatives).
void local_smooth(std::span<const double> time, std::span<const double> x, std::size_t m, double ts,
                  std::span<double> out) {
  const std::size_t n = x.size(), width = std::min(2 * m + 1, n);
  for (std::size_t k = 0; k < n; ++k) {
    // The window of `width` samples centred on k, slid inside the record near its ends.
    std::size_t lo = k >= m ? k - m : 0;
    if (lo + width > n) lo = n - width;
    double s[5] = {0, 0, 0, 0, 0}, r[3] = {0, 0, 0};
    for (std::size_t i = lo; i < lo + width; ++i) {
      const double tau = (time[i] - time[k]) / ts, dx = x[i] - x[k];
      double p = 1;
      for (int q = 0; q < 5; ++q) {
        s[q] += p;
        if (q < 3) r[q] += p * dx;
        p *= tau;
      }
    }
    Eigen::Matrix3d a;
    a << s[0], s[1], s[2], s[1], s[2], s[3], s[2], s[3], s[4];
    const Eigen::Vector3d c = a.partialPivLu().solve(Eigen::Vector3d(r[0], r[1], r[2]));
    out[k] = x[k] + c[0];
  }
}

}  // namespace

void local_polynomial_derivatives(std::span<const double> time, std::span<const double> x,
                                  const DerivativeWindows& windows, std::span<double> velocity,
                                  std::span<double> acceleration) {
  check_record(time, x, 3);
  FRICTION_CHECK(velocity.size() == x.size() && acceleration.size() == x.size(),
                 "sample derivatives: output spans must match the record");
  FRICTION_CHECK(windows.velocity_half_width >= 1 && windows.acceleration_half_width >= 1,
                 "sample derivatives: half widths must be >= 1");
  DerivativeWindows w = windows;
  std::vector<double> intervals(x.size() - 1);
  for (std::size_t k = 1; k < x.size(); ++k) intervals[k - 1] = time[k] - time[k - 1];
  w.sampling_period = statistics::upper_median(intervals);
  apply_local_derivatives<double>(time, x, w, velocity, acceleration);
}

namespace {

// A Welch spectrum of a displacement signal, per bin (white noise of variance v gives v in every
// bin, and a filter G passes (1/L) sum_j |G_j|^2 P_j of it), computed from its second differences
// and divided by their gain 16 sin^4(w/2): the motion's spectrum falls steeply with frequency and
// a taper leaks its low-frequency power into the top of the band; twice differenced it is nearly
// flat.  Hann segments of `length`, half overlapping.
struct Spectrum {
  std::size_t length = 0, segments = 0;
  std::vector<double> p;  // bins 0 .. length/2
  double omega(std::size_t j) const {
    return 2 * std::numbers::pi * static_cast<double>(j) / static_cast<double>(length);
  }
};

Spectrum displacement_spectrum(std::span<const double> x, std::size_t length) {
  Spectrum s;
  s.length = length;
  s.p.assign(length / 2 + 1, 0.0);
  std::vector<double> d(x.size() - 2);
  for (std::size_t k = 1; k + 1 < x.size(); ++k) d[k - 1] = x[k + 1] - 2 * x[k] + x[k - 1];
  std::vector<double> taper(length), segment(length);
  double taper_power = 0;
  for (std::size_t i = 0; i < length; ++i) {
    taper[i] = 0.5 - 0.5 * std::cos(2 * std::numbers::pi * static_cast<double>(i) /
                                    static_cast<double>(length));
    taper_power += taper[i] * taper[i];
  }
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> spectrum;
  for (std::size_t start = 0; start + length <= d.size(); start += length / 2, ++s.segments) {
    double mean = 0;
    for (std::size_t i = 0; i < length; ++i) mean += d[start + i];
    mean /= static_cast<double>(length);
    for (std::size_t i = 0; i < length; ++i) segment[i] = taper[i] * (d[start + i] - mean);
    fft.fwd(spectrum, segment);
    for (std::size_t j = 0; j <= length / 2; ++j) s.p[j] += std::norm(spectrum[j]) / taper_power;
  }
  for (std::size_t j = 0; j <= length / 2; ++j) {
    const double h = std::sin(s.omega(j) / 2);
    s.p[j] = j == 0 ? 0.0 : s.p[j] / static_cast<double>(s.segments) / (16 * h * h * h * h);
  }
  return s;
}

// The level of white noise in the top of the band, w in [0.7 pi, pi], where a friction
// experiment's motion has no power: the median of the bins, corrected to a mean (the median of an
// average of K periodogram ordinates, chi^2 with 2K degrees of freedom, is about (1 - 1/(9K))^3
// of its mean; half-overlapping Hann segments count about as 0.95 K independent ones).
double top_band_level(const Spectrum& s) {
  std::vector<double> top;
  for (std::size_t j = 1; j < s.p.size(); ++j)
    if (s.omega(j) >= 0.7 * std::numbers::pi) top.push_back(s.p[j]);
  const double k = 0.95 * static_cast<double>(s.segments);
  return statistics::upper_median(top) / std::pow(1 - 1 / (9 * k), 3);
}

// A bin holds signal where its power exceeds the noise by this factor (S > N).  Below it the
// optimal filter rejects the bin anyway (passing it adds more noise N than the signal S it keeps,
// Wiener's argument), so leaving such signal out hardly moves the optimum, while the noise
// estimate's own scatter (+-20 % per band for the quantiser model below) would otherwise be read
// as signal where the acceleration's weight w^4 / Ts^4 is largest: with S = P - N everywhere the
// acceleration windows came out 2-8 times too short on multisine records.
constexpr double kSignalOverNoise = 2.0;
constexpr std::size_t kDecisionBins = 4;

// For a symmetric window of 2m+1 uniform samples and powers of tau = i/m, the local polynomial's
// derivatives are rows of the inverse normal equations applied to sums of tau^q x_i: the odd
// powers (tau, or tau and tau^3) give the slope, the even ones (1 and tau^2, or 1, tau^2 and
// tau^4) the curvature.  odd[d] and even[d] hold those rows for degree 2 (d = 0) and 4 (d = 1).
struct FilterRows {
  double odd[2][2] = {{0, 0}, {0, 0}};
  double even[2][3] = {{0, 0, 0}, {0, 0, 0}};
  double value[2][3] = {{0, 0, 0}, {0, 0, 0}};  // the fitted value at the centre
};

std::vector<FilterRows> filter_rows(std::size_t m_max) {
  std::vector<FilterRows> rows(m_max + 1);
  double sums[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};  // sum over i = 1..m of i^q
  for (std::size_t m = 1; m <= m_max; ++m) {
    const double i = static_cast<double>(m);
    double q = 1;
    for (double& s : sums) s += q, q *= i;
    double moment[9];  // sum over i = -m..m of (i/m)^q
    for (int k = 0; k <= 8; ++k)
      moment[k] = k % 2 ? 0.0 : (k == 0 ? 1 + 2 * sums[0] : 2 * sums[k] / std::pow(i, k));
    FilterRows& r = rows[m];
    r.odd[0][0] = 1 / moment[2];
    r.even[0][0] = -moment[2] / (moment[0] * moment[4] - moment[2] * moment[2]);
    r.even[0][1] = moment[0] / (moment[0] * moment[4] - moment[2] * moment[2]);
    r.value[0][0] = moment[4] / (moment[0] * moment[4] - moment[2] * moment[2]);
    r.value[0][1] = -moment[2] / (moment[0] * moment[4] - moment[2] * moment[2]);
    if (m >= 2) {
      Eigen::Matrix2d go;
      go << moment[2], moment[4], moment[4], moment[6];
      const Eigen::Vector2d o = go.inverse().col(0);
      r.odd[1][0] = o[0], r.odd[1][1] = o[1];
      Eigen::Matrix3d ge;
      ge << moment[0], moment[2], moment[4], moment[2], moment[4], moment[6], moment[4], moment[6],
          moment[8];
      const Eigen::Matrix3d gi = ge.inverse();
      const Eigen::Vector3d e = gi.col(1), c = gi.col(0);
      r.even[1][0] = e[0], r.even[1][1] = e[1], r.even[1][2] = e[2];
      r.value[1][0] = c[0], r.value[1][1] = c[1], r.value[1][2] = c[2];
    }
  }
  return rows;
}

// The predicted mean square errors of v and a for every half width, and their minimisers.  For a
// filter H, the ideal derivative D, and P = S + N the measured spectrum of x (signal S, noise N),
//     E = |H - D|^2 S + |H|^2 N = |H|^2 P - 2 Re(H D*) S + |D|^2 S.
// Written so, the noise enters only through Re(H D*) S, which vanishes where the filter rejects;
// written as |H - D|^2 (P - N) it turns a 1 % error in N at the top of the band, where a long
// window's |H - D|^2 ~ |D|^2 is large, into a bias that is not there (that form chose windows 3-10
// times too short on quantised records).  The last term does not depend on m.  S is the bin's
// power times the local signal fraction where the bin holds signal (kSignalOverNoise), 0
// elsewhere.
// Returns what the chosen filters lose against the ideal derivative, per sample: sum |H|^2 P less
// sum Re(H D*) S.  It sits where the filter departs from D, high in the band, where the spectrum
// is reliable; choose_derivative_windows turns it into the regression factors.
struct FilterLoss {
  double velocity = 0, acceleration = 0;
};

// One noise model of the spectrum and what minimise_errors chooses for it: `noise` per bin,
// whether islands of signal above the band count as signal, the windows it sets and their loss.
struct NoiseModel {
  const std::vector<double>* noise;
  bool islands_are_signal;
  DerivativeWindows* windows;
  FilterLoss* loss;
};

// Every noise model is served by one pass over (bin, half width): the filters' responses there do
// not depend on the noise, and they are most of the work (a record's second and third noise
// models, known together, cost one pass).
void minimise_errors(const Spectrum& p, std::span<const NoiseModel> models, double ts,
                     std::size_t n) {
  const std::size_t length = p.length, nmodels = models.size();
  const double lf = static_cast<double>(length);
  const std::size_t m_max = std::max<std::size_t>(1, std::min(length / 4, (n - 1) / 2));
  // Per model, [degree / 2 - 1][m] for degrees 2 and 4: sum Re(H D*) S and sum |H|^2 P.
  struct Sums {
    Eigen::ArrayXd cross_v[2], cross_a[2], pass_v[2], pass_a[2], cross_x[2], pass_x[2];
    double ideal_v = 0, ideal_a = 0;  // sum |D|^2 S
    std::vector<double> n_avg;
    std::size_t band_end = 0;
  };
  std::vector<Sums> sums(nmodels);
  for (Sums& e : sums)
    for (auto* a : {e.cross_v, e.cross_a, e.pass_v, e.pass_a, e.cross_x, e.pass_x})
      for (int d = 0; d < 2; ++d) a[d].setZero(static_cast<Eigen::Index>(m_max + 1));
  // Local averages over +-kDecisionBins bins decide where the signal is, and the bin keeps its
  // own shape through the local signal fraction (a quantiser's lines sit a few bins apart in the
  // record and in its model: compared bin by bin, a line would be read as signal).
  const std::size_t half = length / 2;
  std::vector<double> p_avg(half + 1, 0.0);
  for (std::size_t j = 1; j <= half; ++j) {
    const std::size_t lo = j > kDecisionBins ? j - kDecisionBins : 1;
    const std::size_t hi = std::min(half, j + kDecisionBins);
    for (std::size_t i = lo; i <= hi; ++i) p_avg[j] += p.p[i];
  }
  // The motion of a machine axis is low-pass: its band is the run of signal bins that starts at
  // the lowest frequency.  Islands above it are an encoder's lines (a stroke at constant speed
  // quantises into a sawtooth whose aliased frequency moves by a tenth of the band when the speed
  // changes by 1 %, so no model of the quantiser places them; one such island at 0.9 pi made the
  // acceleration window 2 where 7 was best).
  for (std::size_t k = 0; k < nmodels; ++k) {
    Sums& e = sums[k];
    const std::vector<double>& noise = *models[k].noise;
    e.n_avg.assign(half + 1, 0.0);
    for (std::size_t j = 1; j <= half; ++j) {
      const std::size_t lo = j > kDecisionBins ? j - kDecisionBins : 1;
      const std::size_t hi = std::min(half, j + kDecisionBins);
      for (std::size_t i = lo; i <= hi; ++i) e.n_avg[j] += noise[i];
    }
    while (e.band_end < half && p_avg[e.band_end + 1] > kSignalOverNoise * e.n_avg[e.band_end + 1])
      ++e.band_end;
  }
  // The filters' rows of the inverse normal equations depend on m only (powers of i/m), and so do
  // the scales that turn the unscaled sums below into responses: folded together once per m, they
  // leave a few multiply-adds per (bin, m) where there were six divisions (a third of the rule's
  // time, and the rule a tenth of a diagnosis of data/).
  // gv[d][q], ga[d][q], gx[d][q] at m: H_v = gv0 s1 + gv1 s3; H_a and H_x = g0 (1 + 2 c0) + g1 c2
  // + g2 c4 (the terms a degree does not have are zero, and add exact zeros).
  Eigen::ArrayXd gv[2][2], ga[2][3], gx[2][3];
  {
    const std::vector<FilterRows> rows = filter_rows(m_max);
    const Eigen::Index count = static_cast<Eigen::Index>(m_max + 1);
    for (int d = 0; d < 2; ++d) {
      for (auto& g : gv[d]) g.setZero(count);
      for (auto& g : ga[d]) g.setZero(count);
      for (auto& g : gx[d]) g.setZero(count);
      for (std::size_t m = 1; m <= m_max; ++m) {
        const double i = static_cast<double>(m), i2 = i * i;
        const FilterRows& r = rows[m];
        const Eigen::Index at = static_cast<Eigen::Index>(m);
        // Sums over i = -m..m of (i/m)^q times sin or cos: 2 s1 / i, 2 s3 / i^3, 1 + 2 c0,
        // 2 c2 / i^2, 2 c4 / i^4; H_v = (...) / (ts i), H_a = 2 (...) / (ts^2 i^2).
        const double odd_scale[2] = {2 / i, 2 / (i2 * i)};
        const double even_scale[3] = {1, 2 / i2, 2 / (i2 * i2)};
        const double to_v = 1 / (ts * i), to_a = 2 / (ts * ts * i2);
        for (int q = 0; q <= d; ++q) gv[d][q](at) = r.odd[d][q] * odd_scale[q] * to_v;
        for (int q = 0; q <= d + 1; ++q) {
          ga[d][q](at) = r.even[d][q] * even_scale[q] * to_a;
          gx[d][q](at) = r.value[d][q] * even_scale[q];
        }
      }
    }
  }
  // The responses of one bin, [degree / 2 - 1][m]: H_v = i hv, H_a = ha, H_x = hx; and the unscaled
  // sums they are made of, per m.
  Eigen::ArrayXd hv[2], ha[2], hx[2];
  Eigen::ArrayXd c0s(m_max + 1), c2s(m_max + 1), c4s(m_max + 1), s1s(m_max + 1), s3s(m_max + 1);
  c0s.setZero(), c2s.setZero(), c4s.setZero(), s1s.setZero(), s3s.setZero();
  std::vector<double> signal(nmodels);
  for (std::size_t j = 1; j <= half; ++j) {
    const double total = p.p[j];
    const double wj = p.omega(j), weight = (j == half ? 1.0 : 2.0) / lf;
    const double d_v = wj / ts, d_a = -wj * wj / (ts * ts);
    // Unscaled sums over i = 1..m of i^q cos(w i) (q = 0, 2, 4) and i^q sin(w i) (q = 1, 3); the
    // cosines and sines by rotation through w, taken afresh every 32 steps (a rounding of a few
    // 1e-16 instead of a libm call per term, which was a third of the rule's time).
    const double cw = std::cos(wj), sw = std::sin(wj);
    double c0 = 0, c2 = 0, c4 = 0, s1 = 0, s3 = 0, cs = 1, sn = 0;
    for (std::size_t m = 1; m <= m_max; ++m) {
      const double i = static_cast<double>(m);
      if (m % 32 == 1) {
        cs = std::cos(wj * i), sn = std::sin(wj * i);
      } else {
        const double c_next = cs * cw - sn * sw;
        sn = sn * cw + cs * sw, cs = c_next;
      }
      const double i2 = i * i;
      c0 += cs, c2 += i2 * cs, c4 += i2 * i2 * cs, s1 += i * sn, s3 += i2 * i * sn;
      const Eigen::Index at = static_cast<Eigen::Index>(m);
      c0s(at) = 1 + 2 * c0, c2s(at) = c2, c4s(at) = c4, s1s(at) = s1, s3s(at) = s3;
    }
    for (int d = 0; d < 2; ++d) {
      hv[d] = gv[d][0] * s1s + gv[d][1] * s3s;
      ha[d] = ga[d][0] * c0s + ga[d][1] * c2s + ga[d][2] * c4s;
      hx[d] = gx[d][0] * c0s + gx[d][1] * c2s + gx[d][2] * c4s;
    }
    for (std::size_t k = 0; k < nmodels; ++k) {
      Sums& e = sums[k];
      const bool holds_signal =
          j <= e.band_end ||
          (models[k].islands_are_signal && p_avg[j] > kSignalOverNoise * e.n_avg[j]);
      signal[k] = holds_signal ? total * (1 - e.n_avg[j] / p_avg[j]) : 0.0;
      e.ideal_v += weight * d_v * d_v * signal[k];
      e.ideal_a += weight * d_a * d_a * signal[k];
      const double sv = weight * d_v * signal[k], sa = weight * d_a * signal[k],
                   sx = weight * signal[k], wt = weight * total;
      for (int d = 0; d < 2; ++d) {
        // From m = 1, or 2 for a quartic (it needs five samples).
        const Eigen::Index from = d == 1 ? 2 : 1;
        const Eigen::Index count = static_cast<Eigen::Index>(m_max) + 1 - from;
        if (count <= 0) continue;
        const auto v = hv[d].segment(from, count), a = ha[d].segment(from, count),
                   x = hx[d].segment(from, count);
        e.cross_v[d].segment(from, count) += v * sv;
        e.cross_a[d].segment(from, count) += a * sa;
        e.pass_v[d].segment(from, count) += v * v * wt;
        e.pass_a[d].segment(from, count) += a * a * wt;
        e.cross_x[d].segment(from, count) += x * sx;
        e.pass_x[d].segment(from, count) += x * x * wt;
      }
    }
  }
  for (std::size_t k = 0; k < nmodels; ++k) {
    const Sums& e = sums[k];
    DerivativeWindows& w = *models[k].windows;
    double best_v = INFINITY, best_a = INFINITY, best_x = INFINITY;
    for (int d = 0; d < 2; ++d)
      for (std::size_t m = d == 1 ? 2 : 1; m <= m_max; ++m) {
        // The mean square errors less sum |D|^2 S.
        const double e_v = e.pass_v[d][m] - 2 * e.cross_v[d][m];
        const double e_a = e.pass_a[d][m] - 2 * e.cross_a[d][m];
        if (e_v < best_v) {
          best_v = e_v;
          w.velocity_half_width = m;
          w.velocity_degree = 2 + 2 * static_cast<std::size_t>(d);
        }
        if (e_a < best_a) {
          best_a = e_a;
          w.acceleration_half_width = m;
          w.acceleration_degree = 2 + 2 * static_cast<std::size_t>(d);
        }
        const double e_x = e.pass_x[d][m] - 2 * e.cross_x[d][m];
        if (e_x < best_x) {
          best_x = e_x;
          w.displacement_half_width = m;
          w.displacement_degree = 2 + 2 * static_cast<std::size_t>(d);
        }
      }
    w.velocity_rms_error = std::sqrt(std::max(best_v + e.ideal_v, 0.0));
    w.acceleration_rms_error = std::sqrt(std::max(best_a + e.ideal_a, 0.0));
    const std::size_t dv = w.velocity_degree / 2 - 1, da = w.acceleration_degree / 2 - 1;
    const std::size_t mv = w.velocity_half_width, ma = w.acceleration_half_width;
    if (models[k].loss)
      *models[k].loss = {e.pass_v[dv][mv] - e.cross_v[dv][mv],
                         e.pass_a[da][ma] - e.cross_a[da][ma]};
  }
}

// The rule, without the memo below.
DerivativeWindows windows_by_the_rule(std::span<const double> time, std::span<const double> x) {
  check_record(time, x, 16);
  const std::size_t n = x.size();
  std::vector<double> intervals(n - 1);
  for (std::size_t k = 1; k < n; ++k) intervals[k - 1] = time[k] - time[k - 1];
  DerivativeWindows w;
  const double ts = w.sampling_period = statistics::upper_median(intervals);

  // Segments short enough for >= 16 of them (one segment's periodogram scatters by 100 % per
  // bin), long enough to resolve the filters (128 samples at least, 4096 at most).
  std::size_t length = 128;
  while (length * 2 <= std::min<std::size_t>((n - 2) / 8, 4096)) length *= 2;
  while (length > n - 2) length /= 2;
  const Spectrum p = displacement_spectrum(x, length);

  // First pass: white noise at the top band's level.
  const double white = top_band_level(p);
  std::vector<double> noise(p.p.size(), white);
  FilterLoss lost;
  minimise_errors(p, std::array{NoiseModel{&noise, false, &w, &lost}}, ts, n);
  w.displacement_noise = std::sqrt(white);
  // The displacement the models see: as measured unless an encoder's staircase is removed below
  // (the top band of an exact record holds the broadband power of its reversals' corners, which
  // the derivatives may treat as noise but a presliding curve must keep).
  w.displacement_half_width = 1;
  w.displacement_degree = 2;

  // An encoder: its quantisation error is white only where the motion crosses many steps per
  // sample; near reversals and on slow strokes it is a staircase whose power sits at low and
  // middle frequencies, where a white model would call it signal and choose windows that are too
  // short.  Its spectrum is that of the quantisation error of the motion itself: the record's
  // quantiser (step q, grid through the samples) applied to a smooth estimate of x (local
  // quadratic fits).  The smooth estimate must not keep the staircase itself, or its own
  // quantisation error comes out too small (10 times, at middle frequencies, with a window of 2 on
  // a stroke record): its window is the longer of the first pass's and the shortest whose fitted
  // value keeps at most q/10 of the quantisation error (the value of a quadratic fit at its centre
  // has c(m) = 3(3m^2+3m-1)/((2m+1)(4m^2+4m-3)) of the input's noise variance, and the error is
  // q^2/12: m >= 9).  Noise beyond quantisation shows as an excess at the top of the band and is
  // added as white.
  if (const auto q = signal_quantum(x)) {
    std::size_t m = std::max<std::size_t>(w.velocity_half_width, w.acceleration_half_width);
    auto residual = [](double i) {
      return 3 * (3 * i * i + 3 * i - 1) / ((2 * i + 1) * (4 * i * i + 4 * i - 3)) / 12;
    };
    std::size_t quiet = 1;
    while (residual(static_cast<double>(quiet)) > 0.01) ++quiet;
    m = std::min(std::max(m, quiet), (n - 1) / 2);
    std::vector<double> smooth(n);
    local_smooth(time, x, m, ts, smooth);
    const double grid = x[0] - *q * std::round(x[0] / *q);
    std::vector<double> error(n);
    double variance = 0;
    for (std::size_t k = 0; k < n; ++k) {
      error[k] = grid + *q * std::round((smooth[k] - grid) / *q) - smooth[k];
      variance += error[k] * error[k] / static_cast<double>(n);
    }
    const Spectrum e = displacement_spectrum(error, length);
    const double excess = std::max(white - top_band_level(e), 0.0);
    for (std::size_t j = 0; j < noise.size(); ++j) noise[j] = e.p[j] + excess;
    // The value filter against the quantisation error alone: what it is for is the staircase,
    // and an excess in the top band may be the record's own corners (above).  For the same
    // reason power above the band that the quantiser's model does not explain counts as signal
    // here (a reciprocating motion's harmonics; where they are the quantiser's own lines, the
    // filter keeps a little more of the staircase than it could have removed).  On the
    // tribometer record (200 Hz, 0.1 um encoder) the window is then 7 samples where it was 9.
    DerivativeWindows staircase = w;
    minimise_errors(p,
                    std::array{NoiseModel{&noise, false, &w, &lost},
                               NoiseModel{&e.p, /*islands_are_signal=*/true, &staircase, nullptr}},
                    ts, n);
    w.displacement_noise = std::sqrt(variance + excess);
    w.displacement_half_width = staircase.displacement_half_width;
    w.displacement_degree = staircase.displacement_degree;
  }
  // The regression factors sum(s s_hat) / sum(s_hat^2) = 1 - (what the filter loses) /
  // sum(s_hat^2): a term fitted by least squares on f s_hat is then the term fitted on s, to first
  // order (regression calibration: f s_hat is the least-squares prediction of s from s_hat).  The
  // attenuation of a long window makes f > 1, the noise a short one passes f < 1.  The loss is
  // divided by the estimate's whole mean square: the spectrum of increments has no constant
  // velocity, so a ramp's would be missing from it.
  const double lost_v = lost.velocity, lost_a = lost.acceleration;
  std::vector<double> v(n), a(n);
  apply_local_derivatives<double>(time, x, w, v, a);
  double mean_square_v = 0, mean_square_a = 0;
  for (std::size_t k = 0; k < n; ++k) mean_square_v += v[k] * v[k], mean_square_a += a[k] * a[k];
  mean_square_v /= static_cast<double>(n);
  mean_square_a /= static_cast<double>(n);
  if (mean_square_v > 0 && std::abs(lost_v) < mean_square_v)
    w.velocity_regression_factor = 1 - lost_v / mean_square_v;
  if (mean_square_a > 0 && std::abs(lost_a) < mean_square_a)
    w.acceleration_regression_factor = 1 - lost_a / mean_square_a;
  return w;
}

// A memo of the rule's last results.  A diagnosis asks for the windows of the same two records
// about 200 times (each fit, profile and initial-state estimate builds its own model context;
// 2.7 s of a 24 s diagnosis of data/ on one thread), and the rule is a pure function of the
// samples, so an answer can be reused: the same windows bit for bit.  Keyed by the record's
// length and a 64-bit hash of every sample's time and displacement bits (a collision between
// the few records of one process is about as likely as 1 in 10^17); 16 entries, replaced in
// turn; a mutex makes it safe for the concurrent fits of diagnose and compare.
std::uint64_t record_hash(std::span<const double> time, std::span<const double> x) {
  std::uint64_t h = 0x9e3779b97f4a7c15ULL ^ x.size();
  auto mix = [&h](double v) {
    std::uint64_t z = std::bit_cast<std::uint64_t>(v) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    h ^= z ^ (z >> 31);
  };
  for (std::size_t k = 0; k < x.size(); ++k) {
    mix(time[k]);
    mix(x[k]);
  }
  return h;
}

class WindowMemo {
 public:
  std::optional<DerivativeWindows> find(std::size_t n, std::uint64_t hash) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const Entry& e : entries_)
      if (e.used && e.n == n && e.hash == hash) return e.windows;
    return std::nullopt;
  }
  void add(std::size_t n, std::uint64_t hash, const DerivativeWindows& w) {
    std::lock_guard<std::mutex> lock(mutex_);
    entries_[next_] = {true, n, hash, w};
    next_ = (next_ + 1) % entries_.size();
  }

 private:
  struct Entry {
    bool used = false;
    std::size_t n = 0;
    std::uint64_t hash = 0;
    DerivativeWindows windows;
  };
  std::mutex mutex_;
  std::array<Entry, 16> entries_{};
  std::size_t next_ = 0;
};

WindowMemo& window_memo() {
  static WindowMemo memo;
  return memo;
}

}  // namespace

DerivativeWindows choose_derivative_windows(std::span<const double> time,
                                            std::span<const double> x) {
  check_record(time, x, 16);
  const std::uint64_t hash = record_hash(time, x);
  if (auto w = window_memo().find(x.size(), hash)) return *w;
  const DerivativeWindows w = windows_by_the_rule(time, x);
  window_memo().add(x.size(), hash, w);
  return w;
}

SampleDerivatives sample_derivatives(std::span<const double> time, std::span<const double> x) {
  SampleDerivatives s;
  s.windows = choose_derivative_windows(time, x);
  s.velocity.resize(x.size());
  s.acceleration.resize(x.size());
  local_polynomial_derivatives(time, x, s.windows, s.velocity, s.acceleration);
  return s;
}

}  // namespace friction
