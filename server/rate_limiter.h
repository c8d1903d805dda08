// A token bucket: `rate` commands a second on average, bursts of up to `burst`.
#pragma once
#include <algorithm>
#include <chrono>

namespace cellphys::server {

class RateLimiter {
 public:
  using Clock = std::chrono::steady_clock;
  RateLimiter(double rate, double burst) : rate_(rate), burst_(burst), tokens_(burst), at_(Clock::now()) {}

  /// Takes one token if there is one.
  bool take(Clock::time_point now = Clock::now()) {
    tokens_ = std::min(burst_, tokens_ + rate_ * std::chrono::duration<double>(now - at_).count());
    at_ = now;
    if (tokens_ < 1.0) return false;
    tokens_ -= 1.0;
    return true;
  }

 private:
  double rate_, burst_, tokens_;
  Clock::time_point at_;
};

}  // namespace cellphys::server
