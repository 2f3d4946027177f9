// Numbers in messages, warnings and reports: printf's %g at a given number of significant digits.
// Private to the library: one definition instead of a copy in each source file that prints.
#pragma once

#include <cstdio>
#include <string>

namespace friction {

inline std::string format_number(double v, int significant_digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", significant_digits, v);
  return buf;
}

}  // namespace friction
