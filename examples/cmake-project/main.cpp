// Feed-forward friction compensation for one machine axis, built against an installed `friction`.
//
// A position controller runs at a fixed rate.  At every tick it reads the reference position
// x_ref(t) of the axis, steps a Maxwell Slip friction model with the reference increment and adds
// the predicted friction force to the drive command (on top of the inertia feed-forward m * a_ref):
//
//     u(t) = m * a_ref(t) + F_model(x_ref up to t)
//
// Driving the model with the reference rather than the measured position keeps encoder noise out
// of the compensation and makes it available before the axis moves.  The model is constructed once,
// outside the loop; `step` is allocation-free and noexcept, so it can live in a real-time task.
//
// The program checks what it prints: once every operator slips, the compensation must equal the
// sliding friction sum_i k_i Delta_i (Maxwell Slip eq. 5), and the loop must not allocate.  It
// exits non-zero otherwise, which is what the install test of the project relies on.
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <numbers>

#include "friction/maxwell_slip.hpp"
#include "friction/model_io.hpp"
#include "friction/version.hpp"

// Only to prove the "no allocation per tick" claim: count global operator new calls.  A real
// controller does not need this.
namespace {
std::atomic<long> g_allocations{0};
}
void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

// With a saved model (the JSON that `friction-identify identify --out` or `generate --truth`
// writes): load it at start-up, then run the same control loop with it.  The model is checked to
// give a finite compensation that resists the reference motion while sliding, without allocating.
int run_saved_model(const char* path) {
  friction::AnyModel model = friction::AnyModel::load(path);
  model.reset();
  constexpr double ts = 1e-3;
  constexpr double omega = 2.0 * std::numbers::pi * 0.5;
  constexpr double amplitude = 100e-6;
  double previous = 0.0, peak = 0.0, work = 0.0;
  bool finite = true;
  const long allocations_before = g_allocations.load();
  for (int k = 1; k <= 4000; ++k) {
    const double x = amplitude * std::sin(omega * k * ts);
    const double dx = x - previous;
    previous = x;
    const double f = model.step(friction::Motion<double>{dx, dx / ts, ts});
    finite = finite && std::isfinite(f);
    peak = std::fmax(peak, std::fabs(f));
    work += f * dx;  // friction resists the motion: positive work by the drive
  }
  const long loop_allocations = g_allocations.load() - allocations_before;
  std::printf(
      "saved %s model from %s: peak compensation %.6f N, drive work %.3e J, "
      "allocations in the loop: %ld\n",
      model.type().c_str(), path, peak, work, loop_allocations);
  const bool ok = finite && peak > 0.0 && work > 0.0 && loop_allocations == 0;
  std::printf("%s\n", ok ? "saved-model check: OK" : "saved-model check: FAILED");
  return ok ? EXIT_SUCCESS : EXIT_FAILURE;
}

int main(int argc, char** argv) {
  if (argc > 1) return run_saved_model(argv[1]);

  // Four elasto-slide operators, as identified for a small linear axis (SI units).
  const double stiffness[] = {4e4, 3e4, 2e4, 1e4};       // k_i [N/m]
  const double threshold[] = {1e-6, 3e-6, 7e-6, 15e-6};  // Delta_i [m]
  double expected_sliding = 0.0;                         // sum_i k_i Delta_i [N]
  for (int i = 0; i < 4; ++i) expected_sliding += stiffness[i] * threshold[i];

  friction::MaxwellSlip<double> model(
      {{std::begin(stiffness), std::end(stiffness)}, {std::begin(threshold), std::end(threshold)}});

  // Reference: a 100 um, 0.5 Hz sinusoidal stroke, sampled by a 1 kHz control loop for 4 s.
  constexpr double rate = 1000.0;  // [Hz]
  constexpr double ts = 1.0 / rate;
  constexpr double amplitude = 100e-6;  // [m]
  constexpr double omega = 2.0 * std::numbers::pi * 0.5;
  constexpr double mass = 2.5;  // moving mass of the axis [kg]
  constexpr int ticks = 4000;
  auto x_ref = [&](double t) { return amplitude * std::sin(omega * t); };

  double peak_friction = 0.0;  // largest |F_model| seen [N]
  double peak_command = 0.0;   // largest |u| seen [N]
  int sliding_ticks = 0;
  double previous = x_ref(0.0);
  const long allocations_before = g_allocations.load();
  for (int k = 1; k <= ticks; ++k) {
    const double t = k * ts;
    const double x = x_ref(t);
    const double dx = x - previous;
    previous = x;
    const double a_ref = -omega * omega * x;
    const double f_friction = model.step(friction::Motion<double>{dx, dx / ts, ts});
    const double command = mass * a_ref + f_friction;
    peak_friction = std::fmax(peak_friction, std::fabs(f_friction));
    peak_command = std::fmax(peak_command, std::fabs(command));
    if (model.sliding()) ++sliding_ticks;
  }
  const long loop_allocations = g_allocations.load() - allocations_before;

  const double sliding_level = model.parameters().sliding_force();
  std::printf("friction %s: %d ticks at %.0f Hz, %d operators\n", friction::version(), ticks, rate,
              static_cast<int>(model.size()));
  std::printf("peak friction compensation: %.9f N\n", peak_friction);
  std::printf("peak drive command:         %.9f N\n", peak_command);
  std::printf("sliding level sum k_i*Delta_i: %.9f N (%d of %d ticks sliding)\n", sliding_level,
              sliding_ticks, ticks);
  std::printf("allocations in the control loop: %ld\n", loop_allocations);

  const double tolerance = 1e-9 * expected_sliding;
  const bool ok = std::fabs(peak_friction - expected_sliding) <= tolerance &&
                  std::fabs(sliding_level - expected_sliding) <= tolerance && sliding_ticks > 0 &&
                  sliding_ticks < ticks && loop_allocations == 0;
  std::printf("%s\n", ok ? "compensation check: OK" : "compensation check: FAILED");
  return ok ? EXIT_SUCCESS : EXIT_FAILURE;
}
