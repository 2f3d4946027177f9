// Velocity and acceleration at the sample instants (see sample_derivatives.hpp).
#include "friction/sample_derivatives.hpp"

#include <Eigen/Core>
#include <Eigen/LU>
#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "friction/error.hpp"
#include "friction/signals.hpp"

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

double median_of(std::vector<double> v) {
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(h), v.end());
  return v[h];
}

// One pass of local quadratic fits with half width m; writes the fitted value (order 0), the first
// (order 1) or the second (order 2) derivative at every sample.
void local_fit(std::span<const double> time, std::span<const double> x, std::size_t m, int order,
               double ts, std::span<double> out) {
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
    out[k] = order == 0 ? x[k] + c[0] : order == 1 ? c[1] / ts : 2 * c[2] / (ts * ts);
  }
}

}  // namespace

void local_polynomial_derivatives(std::span<const double> time, std::span<const double> x,
                                  std::size_t velocity_half_width,
                                  std::size_t acceleration_half_width, std::span<double> velocity,
                                  std::span<double> acceleration) {
  check_record(time, x, 3);
  FRICTION_CHECK(velocity.size() == x.size() && acceleration.size() == x.size(),
                 "sample derivatives: output spans must match the record");
  FRICTION_CHECK(velocity_half_width >= 1 && acceleration_half_width >= 1,
                 "sample derivatives: half widths must be >= 1");
  std::vector<double> intervals(x.size() - 1);
  for (std::size_t k = 1; k < x.size(); ++k) intervals[k - 1] = time[k] - time[k - 1];
  const double ts = median_of(intervals);
  local_fit(time, x, velocity_half_width, 1, ts, velocity);
  local_fit(time, x, acceleration_half_width, 2, ts, acceleration);
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
  return median_of(top) / std::pow(1 - 1 / (9 * k), 3);
}

// A bin holds signal where its power exceeds the noise by this factor (S > N).  Below it the
// optimal filter rejects the bin anyway (passing it adds more noise N than the signal S it keeps,
// Wiener's argument), so leaving such signal out hardly moves the optimum, while the noise
// estimate's own scatter (+-20 % per band for the quantiser model below) would otherwise be read
// as signal where the acceleration's weight w^4 / Ts^4 is largest: with S = P - N everywhere the
// acceleration windows came out 2-8 times too short on multisine records.
constexpr double kSignalOverNoise = 2.0;
constexpr std::size_t kDecisionBins = 4;

// The predicted mean square errors of v and a for every half width, and their minimisers.  For a
// filter H, the ideal derivative D, and P = S + N the measured spectrum of x (signal S, noise N),
//     E = |H - D|^2 S + |H|^2 N = |H|^2 P - 2 Re(H D*) S + |D|^2 S.
// Written so, the noise enters only through Re(H D*) S, which vanishes where the filter rejects;
// written as |H - D|^2 (P - N) it turns a 1 % error in N at the top of the band, where a long
// window's |H - D|^2 ~ |D|^2 is large, into a bias that is not there (that form chose windows 3-10
// times too short on quantised records).  The last term does not depend on m.  S is the bin's
// power times the local signal fraction where the bin holds signal (kSignalOverNoise), 0
// elsewhere.
void minimise_errors(const Spectrum& p, const std::vector<double>& noise, double ts, std::size_t n,
                     DerivativeWindows& w) {
  const std::size_t length = p.length;
  const double lf = static_cast<double>(length);
  const std::size_t m_max = std::max<std::size_t>(1, std::min(length / 4, (n - 1) / 2));
  std::vector<double> e_v(m_max + 1, 0.0), e_a(m_max + 1, 0.0);
  double ideal_v = 0, ideal_a = 0;  // sum |D|^2 S
  // Local averages over +-kDecisionBins bins decide where the signal is, and the bin keeps its
  // own shape through the local signal fraction (a quantiser's lines sit a few bins apart in the
  // record and in its model: compared bin by bin, a line would be read as signal).
  const std::size_t half = length / 2;
  std::vector<double> p_avg(half + 1, 0.0), n_avg(half + 1, 0.0);
  for (std::size_t j = 1; j <= half; ++j) {
    const std::size_t lo = j > kDecisionBins ? j - kDecisionBins : 1;
    const std::size_t hi = std::min(half, j + kDecisionBins);
    for (std::size_t i = lo; i <= hi; ++i) {
      p_avg[j] += p.p[i];
      n_avg[j] += noise[i];
    }
  }
  // The motion of a machine axis is low-pass: its band is the run of signal bins that starts at
  // the lowest frequency.  Islands above it are an encoder's lines (a stroke at constant speed
  // quantises into a sawtooth whose aliased frequency moves by a tenth of the band when the speed
  // changes by 1 %, so no model of the quantiser places them; one such island at 0.9 pi made the
  // acceleration window 2 where 7 was best).
  std::size_t band_end = 0;
  while (band_end < half && p_avg[band_end + 1] > kSignalOverNoise * n_avg[band_end + 1])
    ++band_end;
  for (std::size_t j = 1; j <= length / 2; ++j) {
    const double total = p.p[j];
    const double signal = j <= band_end ? total * (1 - n_avg[j] / p_avg[j]) : 0.0;
    const double wj = p.omega(j), weight = (j == length / 2 ? 1.0 : 2.0) / lf;
    const double d_v = wj / ts, d_a = -wj * wj / (ts * ts);
    ideal_v += weight * d_v * d_v * signal;
    ideal_a += weight * d_a * d_a * signal;
    double sum_isin = 0, sum_i2cos = 0, sum_cos = 0;
    for (std::size_t m = 1; m <= m_max; ++m) {
      const double i = static_cast<double>(m);
      sum_isin += i * std::sin(wj * i);
      sum_i2cos += i * i * std::cos(wj * i);
      sum_cos += std::cos(wj * i);
      const double s2 = i * (i + 1) * (2 * i + 1) / 3;
      const double s4 = i * (i + 1) * (2 * i + 1) * (3 * i * i + 3 * i - 1) / 15;
      const double mu2 = s2 / (2 * i + 1), dd = s4 - s2 * s2 / (2 * i + 1);
      const double h_v = 2 * sum_isin / (s2 * ts);  // H = i h_v, D = i d_v
      const double h_a = 2 / (ts * ts * dd) * (2 * sum_i2cos - mu2 * (1 + 2 * sum_cos));
      e_v[m] += weight * (h_v * h_v * total - 2 * h_v * d_v * signal);
      e_a[m] += weight * (h_a * h_a * total - 2 * h_a * d_a * signal);
    }
  }
  double best_v = INFINITY, best_a = INFINITY;
  for (std::size_t m = 1; m <= m_max; ++m) {
    if (e_v[m] < best_v) {
      best_v = e_v[m];
      w.velocity_half_width = m;
    }
    if (e_a[m] < best_a) {
      best_a = e_a[m];
      w.acceleration_half_width = m;
    }
  }
  w.velocity_rms_error = std::sqrt(std::max(best_v + ideal_v, 0.0));
  w.acceleration_rms_error = std::sqrt(std::max(best_a + ideal_a, 0.0));
}

}  // namespace

DerivativeWindows choose_derivative_windows(std::span<const double> time,
                                            std::span<const double> x) {
  check_record(time, x, 16);
  const std::size_t n = x.size();
  std::vector<double> intervals(n - 1);
  for (std::size_t k = 1; k < n; ++k) intervals[k - 1] = time[k] - time[k - 1];
  DerivativeWindows w;
  const double ts = w.sampling_period = median_of(intervals);

  // Segments short enough for >= 16 of them (one segment's periodogram scatters by 100 % per
  // bin), long enough to resolve the filters (128 samples at least, 4096 at most).
  std::size_t length = 128;
  while (length * 2 <= std::min<std::size_t>((n - 2) / 8, 4096)) length *= 2;
  while (length > n - 2) length /= 2;
  const Spectrum p = displacement_spectrum(x, length);

  // First pass: white noise at the top band's level.
  const double white = top_band_level(p);
  std::vector<double> noise(p.p.size(), white);
  minimise_errors(p, noise, ts, n, w);
  w.displacement_noise = std::sqrt(white);

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
    local_fit(time, x, m, 0, ts, smooth);
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
    minimise_errors(p, noise, ts, n, w);
    w.displacement_noise = std::sqrt(variance + excess);
  }
  return w;
}

SampleDerivatives sample_derivatives(std::span<const double> time, std::span<const double> x) {
  SampleDerivatives s;
  s.windows = choose_derivative_windows(time, x);
  s.velocity.resize(x.size());
  s.acceleration.resize(x.size());
  local_polynomial_derivatives(time, x, s.windows.velocity_half_width,
                               s.windows.acceleration_half_width, s.velocity, s.acceleration);
  return s;
}

}  // namespace friction
