// The steps of identify_extensions (extension_identification.hpp), private to the library: the
// Maxwell Slip path with its restart (extension_identify_slip.cpp), the held LuGre / DNLRX path
// (extension_identify_held.cpp) and what both share (extension_identification.cpp).
#pragma once

#include <string>
#include <vector>

#include "friction/dnlrx.hpp"
#include "friction/extension_fit.hpp"
#include "friction/extension_identification.hpp"
#include "friction/lugre.hpp"
#include "friction/maxwell_slip.hpp"
#include "friction/record.hpp"

namespace friction::extension_detail {

class JointFitMemo;

/// Velocity and acceleration of a record at its sample instants, as simulate_extended gives the
/// pieces (no delay).
struct RecordSignals {
  std::vector<double> v, a;
};
RecordSignals record_signals(const Record& r);

/// Relative initial state values_i / thresholds_i (0 where values are missing).
std::vector<double> state_from(const std::vector<double>& values,
                               const std::vector<double>& thresholds);

/// The pieces in the order of a joint start: the velocity pieces before the lag that acts through
/// them.
std::vector<Effect> velocity_pieces_first(std::vector<Effect> effects);

/// A warning when the joint covariance is rank deficient, naming the pieces' parameters left
/// without a standard error (those that trade off against others on the record).
void note_rank_deficiency(ExtensionIdentification& res, bool rank_deficient);

/// Warnings about the pieces: bounds and missing evidence (header comment, 3).
void judge_evidence(ExtensionIdentification& res, const std::vector<Effect>& effects, double f0,
                    double sigmas);

/// fit_extended_slip, stopped early when it cannot end below `target_rss` [N^2]: at the pace of
/// its last iterations (detail::HopelessSearch, bounded_solver.hpp) its remaining budget would not
/// get it there.  A stopped fit returns where it stopped (ok, its RSS above the target).  Infinity:
/// fit_extended_slip.  For a fit whose only use is to beat a known RSS: the restart's, and a
/// diagnosis candidate's (the RSS the acceptance rules could pass).  `stopped`, when given, says
/// whether it stopped early; `settled_trust_region`: judged only over iterations in which its
/// trust region settled (HopelessSearch).
ExtendedSlipFit fit_extended_slip_within_reach(const Record& r,
                                               const MaxwellSlipParameters<double>& base0,
                                               const std::vector<double>& rho0,
                                               const ExtensionParameters<double>& ext0,
                                               bool fix_theta, int max_iterations,
                                               double target_rss, bool* stopped = nullptr,
                                               bool settled_trust_region = false);

/// The restart (section 1): NLR (order selected again) on the force without the pieces, the joint
/// fit from that base; the fit with the lower BIC is returned (`restarted` says which), then
/// grown one operator at a time while BIC falls (o.grow_operators, section 1: Order growth).
/// `keep_order`: the restart's NLR fits the M of `cur` instead of selecting it (growth still
/// follows).  `memo`: the joint fits from NLR's bases are made through it (joint_fit_memo.hpp).
ExtendedSlipFit restart_base(const Record& r, const ExtendedSlipFit& cur,
                             const ExtensionFitOptions& o, bool& restarted,
                             bool keep_order = false, JointFitMemo* memo = nullptr);

/// Maxwell Slip base: the base and all pieces refitted jointly, with the restart (section 1).
void identify_on_maxwell_slip(ExtensionIdentification& res,
                              const MaxwellSlipParameters<double>& base0, const Record& r,
                              const std::vector<double>& base_initial, std::vector<Effect> effects,
                              const ExtensionFitOptions& o);

/// DNLRX / LuGre bases: the pieces with the base held, then everything jointly (section 2).
/// `base_initial` holds the base's deflections (DNLRX) or z0 (LuGre).
void identify_on_dnlrx(ExtensionIdentification& res, const DnlrxParameters<double>& base,
                       const Record& r, const std::vector<double>& base_simulated,
                       const std::vector<double>& base_initial, const std::vector<Effect>& effects,
                       const ExtensionFitOptions& o);
void identify_on_lugre(ExtensionIdentification& res, const LuGreParameters<double>& base,
                       const Record& r, const std::vector<double>& base_simulated,
                       const std::vector<double>& base_initial, const std::vector<Effect>& effects,
                       const ExtensionFitOptions& o);

}  // namespace friction::extension_detail
