#include "friction/version.hpp"

namespace friction {
const char* version() noexcept {
  return FRICTION_VERSION_STRING;
}
}  // namespace friction
