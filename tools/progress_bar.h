// A progress bar on stderr for runs longer than a second, when stderr is a terminal (never in a
// pipe or a log, so a run's stderr there holds only warnings and errors).
#pragma once
#include <chrono>

namespace cellphys::cli {

class ProgressBar {
 public:
  explicit ProgressBar(long long total);
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  ~ProgressBar() { finish(); }

  // `done` of the total steps are done; redrawn at most every 0.1 s.
  void update(long long done);
  // Clears the bar, if shown.
  void finish();

 private:
  using Clock = std::chrono::steady_clock;
  long long total_;
  bool enabled_, shown_ = false;
  Clock::time_point start_, last_{};
};

}  // namespace cellphys::cli
