// Subnormal numbers flushed to zero while the library's fits run.
//
// A double below 2.2e-308 in magnitude (subnormal) is handled by microcode on x86: an operation
// that takes or gives one costs tens to a hundred times a normal one.  The fits make them in
// bulk, and none of them carries information.  Measured on `diagnose` of data/ (perf, one
// thread, with and without the flush; README, "Subnormal numbers"):
//
//   - the Stribeck weight exp(-(|v|/vs)^q) (stribeck.hpp) falls through 1e-300 over a band of
//     speeds above vs; its Jet lanes and their products (the slip limits scaled by it, the
//     operators' deflections against them) follow it below 2.2e-308: with the flush, the time
//     in the weight's Jet code and in the Jet products fell by 97 % and 89 %;
//   - the Gram matrices of the compressed problems (compressed_cost.hpp) square such Jacobian
//     entries: 1.45 s of an 8.6 s run, 0.18 s with the flush.
//
// Every quantity of a fit is scaled to the force, the record's speeds and travel (1e-9 to 1e6),
// so a product below 2.2e-308 is zero to every digit any result keeps: the diagnosis of data/
// names the same effects with the same parameters to 1e-14 relative (but a dead operator's
// stiffness of 1e-31 N/m), 38 % faster (8.6 -> 5.3 s on one thread).
//
// `SubnormalsFlushed` sets flush-to-zero (results) and denormals-are-zero (inputs) on the calling
// thread for its lifetime and restores the caller's mode on exit, exceptions included (the
// exception flags raised meanwhile stay raised): a controller that links the library keeps its
// own floating-point mode.  The public drivers (identification, validation, diagnosis, the CLI)
// hold one; `parallel_for` gives its workers the mode of the thread that started them, so a
// result does not depend on the thread count.  Where the hardware has no such mode (not x86
// SSE, not AArch64) both are no-ops.
#pragma once

#if defined(__SSE2__) || defined(_M_X64)
#include <xmmintrin.h>
#define FRICTION_FP_MODE_SSE 1
#elif defined(__aarch64__)
#define FRICTION_FP_MODE_AARCH64 1
#endif

namespace friction::detail {

#if defined(FRICTION_FP_MODE_SSE)
// MXCSR's bits 0-5 are the sticky exception flags, not the mode: they are left as they are.
inline constexpr unsigned kMxcsrFlags = 0x3f;
#endif

/// The calling thread's floating-point controls (MXCSR without its exception flags on x86, FPCR
/// on AArch64; 0 elsewhere).
inline unsigned long long floating_point_mode() noexcept {
#if defined(FRICTION_FP_MODE_SSE)
  return _mm_getcsr() & ~kMxcsrFlags;
#elif defined(FRICTION_FP_MODE_AARCH64)
  unsigned long long fpcr;
  __asm__ volatile("mrs %0, fpcr" : "=r"(fpcr));
  return fpcr;
#else
  return 0;
#endif
}

/// Sets the calling thread's floating-point controls (a value floating_point_mode gave); the
/// exception flags raised so far stay raised.
inline void set_floating_point_mode(unsigned long long mode) noexcept {
#if defined(FRICTION_FP_MODE_SSE)
  _mm_setcsr((static_cast<unsigned>(mode) & ~kMxcsrFlags) | (_mm_getcsr() & kMxcsrFlags));
#elif defined(FRICTION_FP_MODE_AARCH64)
  __asm__ volatile("msr fpcr, %0" : : "r"(mode));
#else
  (void)mode;
#endif
}

/// The control word with subnormal results and inputs taken as zero.
inline unsigned long long with_subnormals_flushed(unsigned long long mode) noexcept {
#if defined(FRICTION_FP_MODE_SSE)
  constexpr unsigned long long kFlushToZero = 0x8000, kDenormalsAreZero = 0x0040;
  return mode | kFlushToZero | kDenormalsAreZero;
#elif defined(FRICTION_FP_MODE_AARCH64)
  constexpr unsigned long long kFlushToZero = 1ull << 24;  // FPCR.FZ: inputs and results
  return mode | kFlushToZero;
#else
  return mode;
#endif
}

/// Flush-to-zero on this thread for the guard's lifetime (see the header comment).
class SubnormalsFlushed {
 public:
  SubnormalsFlushed() noexcept : saved_(floating_point_mode()) {
    set_floating_point_mode(with_subnormals_flushed(saved_));
  }
  ~SubnormalsFlushed() { set_floating_point_mode(saved_); }
  SubnormalsFlushed(const SubnormalsFlushed&) = delete;
  SubnormalsFlushed& operator=(const SubnormalsFlushed&) = delete;

 private:
  unsigned long long saved_;
};

}  // namespace friction::detail
