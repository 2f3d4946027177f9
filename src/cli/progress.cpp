#include "progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>

namespace friction::cli {

Progress::Progress(bool enabled)
    : active_(enabled && isatty(STDERR_FILENO) == 1 && std::getenv("CI") == nullptr) {}

Progress::~Progress() {
  done();
}

void Progress::update(const std::string& message) {
  if (!active_) return;
  const auto now = std::chrono::steady_clock::now();
  if (shown_ && now - last_ < std::chrono::milliseconds(200)) return;
  last_ = now;
  std::fprintf(stderr, "\r\033[K%s", message.c_str());
  std::fflush(stderr);
  shown_ = true;
}

void Progress::done() {
  if (!active_ || !shown_) return;
  std::fprintf(stderr, "\r\033[K");
  std::fflush(stderr);
  shown_ = false;
}

}  // namespace friction::cli
