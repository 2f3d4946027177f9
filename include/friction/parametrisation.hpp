// How a parameter is fitted: directly (linear) or through its logarithm (log).
//
// A standard error and a 95 % interval mean something only in the coordinate the optimiser moved:
// the Gauss-Newton covariance is that of the fitted coordinate.  A log-fitted parameter (Maxwell
// Slip stiffnesses and thresholds, the LG parameters) has a log-normal interval
// [v exp(-1.96 s), v exp(1.96 s)] with s the standard error of ln v, and the standard error v s in
// its own units; a linearly fitted one (DNLRX filters, the extension pieces, the LuGre parameters
// when refitted with pieces) has the symmetric interval v -+ 1.96 s.  covariance_report.hpp applies
// this; the effect table (effect_table.hpp) says how each piece parameter is fitted.
#pragma once

namespace friction {

enum class Parametrisation { linear, log };

}  // namespace friction
