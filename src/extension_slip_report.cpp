// Standard errors of a joint Maxwell Slip + pieces fit (extension_fit.hpp).
#include <cmath>

#include "extension_families.hpp"
#include "friction/extension_fit.hpp"

namespace friction {

ExtendedSlipReport report_extended_slip(const Record& r, const ExtendedSlipFit& fit) {
  using namespace extension_detail;
  const double f0ref =
      fit.ext.reference_force > 0 ? fit.ext.reference_force : fit.base.sliding_force();
  const SlipFamily family{fit.base, true, fit.ext.frictional_lag.has_value()};
  const Box box = state_box(family, r);
  std::vector<char> free_state(fit.rho.size(), 1);
  for (std::size_t i = 0; i < fit.rho.size(); ++i)
    if (at_bound(fit.rho[i], box.lower[i]) || at_bound(fit.rho[i], box.upper[i]) ||
        (i < fit.base.size() && std::abs(fit.rho[i]) >= 1.0 - 1e-9))
      free_state[i] = 0;
  const JointReport joint =
      report_joint_fit(r, family, family.base_theta(), fit.ext, fit.rho, free_state, f0ref,
                       own_reference_ratio(fit.ext, fit.base.sliding_force()));
  return {joint.pieces, joint.base, joint.correlation, joint.rank_deficient};
}

}  // namespace friction
