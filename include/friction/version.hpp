#pragma once

#define FRICTION_VERSION_STRING "0.1.0"

namespace friction {
/// Library version, "MAJOR.MINOR.PATCH".
const char* version() noexcept;
}  // namespace friction
