// Progress on stderr for work that takes more than a moment: shown when stderr is a terminal and
// the run is not under CI, silent in scripts.
#pragma once

#include <chrono>
#include <string>

namespace friction::cli {

class Progress {
 public:
  /// `enabled` false forces silence (e.g. --quiet).
  explicit Progress(bool enabled = true);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  /// Replaces the status line (rate-limited to a few updates a second).
  void update(const std::string& message);
  /// Clears the status line.
  void done();
  bool active() const noexcept { return active_; }

 private:
  bool active_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace friction::cli
