// Joint fits of one record remembered by every number they start from, for a diagnosis that asks
// for the same fit twice.
//
// The final polish (diagnose_candidates.cpp, polish_final) restarts the last model from NLR with
// the global stage; the restart after the last finding did the same without it.  When the model
// has not changed since and the global stage moves nothing, NLR hands the joint fits the same
// bases and states as before, and each fit would repeat itself: fit_extended_slip is a function
// of its arguments (the same numbers in, the same numbers out, on any number of threads).  On
// data/ that was both of the polish's restart fits.  So the fits are remembered by their
// arguments, bit for bit, and a fit asked again is the fit made before; any other argument, in
// any bit, makes a new fit.  Only a few of the latest are kept: the polish asks for the fits of
// the restart just before it.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string_view>
#include <utility>
#include <vector>

#include "friction/extension_fit.hpp"
#include "friction/record.hpp"
#include "extension_steps.hpp"

namespace friction::extension_detail {

class JointFitMemo {
 public:
  /// Fits kept (the restart before the polish makes at most four).
  static constexpr std::size_t kKept = 8;

  /// For the fits of `r`, which must outlive the memo unchanged.
  explicit JointFitMemo(const Record& r) : record_(&r) {}
  JointFitMemo(const JointFitMemo&) = delete;
  JointFitMemo& operator=(const JointFitMemo&) = delete;

  /// fit_extended_slip_within_reach(r, base, rho, ext, false, max_iterations, target_rss)
  /// (extension_steps.hpp), made once for each distinct set of arguments while it is kept.  Safe
  /// to call from several threads; two threads asking for the same new fit at once both make it
  /// (the same fit).  A fit that throws is not remembered.
  ExtendedSlipFit fit(const Record& r, const MaxwellSlipParameters<double>& base,
                      const std::vector<double>& rho, const ExtensionParameters<double>& ext,
                      int max_iterations, double target_rss) {
    if (&r != record_)
      return fit_extended_slip_within_reach(r, base, rho, ext, false, max_iterations, target_rss);
    std::vector<std::uint64_t> key = key_of(base, rho, ext, max_iterations, target_rss);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& [k, f] : fits_)
        if (k == key) return f;
    }
    ExtendedSlipFit f =
        fit_extended_slip_within_reach(r, base, rho, ext, false, max_iterations, target_rss);
    const std::lock_guard<std::mutex> lock(mutex_);
    ++made_;
    fits_.emplace_back(std::move(key), f);
    if (fits_.size() > kKept) fits_.pop_front();
    return f;
  }

  /// Fits made (not returned from memory) so far.
  std::size_t made() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return made_;
  }

 private:
  // Every argument as bits: the iteration cap, the target, the base, the state, and each piece
  // present with its effect and every parameter in the pieces' own order, then the reference
  // force.
  static std::vector<std::uint64_t> key_of(const MaxwellSlipParameters<double>& base,
                                           const std::vector<double>& rho,
                                           const ExtensionParameters<double>& ext,
                                           int max_iterations, double target_rss) {
    std::vector<std::uint64_t> key;
    key.reserve(5 + 2 * base.size() + rho.size() + 2 * ext.parameter_count());
    key.push_back(static_cast<std::uint64_t>(static_cast<std::int64_t>(max_iterations)));
    key.push_back(std::bit_cast<std::uint64_t>(target_rss));
    key.push_back(base.size());
    for (std::size_t i = 0; i < base.size(); ++i) {
      key.push_back(std::bit_cast<std::uint64_t>(base.stiffness[i]));
      key.push_back(std::bit_cast<std::uint64_t>(base.threshold[i]));
    }
    key.push_back(rho.size());
    for (double v : rho) key.push_back(std::bit_cast<std::uint64_t>(v));
    ext.for_each_parameter([&](Effect e, std::string_view, const double& v) {
      key.push_back(static_cast<std::uint64_t>(e));
      key.push_back(std::bit_cast<std::uint64_t>(v));
    });
    key.push_back(std::bit_cast<std::uint64_t>(ext.reference_force));
    return key;
  }

  const Record* record_;
  mutable std::mutex mutex_;
  std::deque<std::pair<std::vector<std::uint64_t>, ExtendedSlipFit>> fits_;
  std::size_t made_ = 0;
};

}  // namespace friction::extension_detail
