#include "tools/progress_bar.h"

#include <unistd.h>

#include <cstdio>

namespace cellphys::cli {

ProgressBar::ProgressBar(long long total) : total_(total), enabled_(::isatty(2) == 1), start_(Clock::now()) {}

void ProgressBar::update(long long done) {
  if (!enabled_ || total_ <= 0) return;
  const auto now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  if (elapsed < 1.0 || std::chrono::duration<double>(now - last_).count() < 0.1) return;
  last_ = now;
  const double frac = double(done) / double(total_);
  const int width = 30, fill = static_cast<int>(frac * width);
  const double eta = done > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
  std::fprintf(stderr, "\r[%.*s%.*s] %3d%% step %lld/%lld, %.0f s left ", fill, "##############################",
               width - fill, "..............................", static_cast<int>(100 * frac), done, total_, eta);
  std::fflush(stderr);
  shown_ = true;
}

void ProgressBar::finish() {
  if (shown_) std::fprintf(stderr, "\r\033[K");
  shown_ = false;
}

}  // namespace cellphys::cli
