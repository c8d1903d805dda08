#include "tools/interrupt.h"

#include <atomic>
#include <csignal>

namespace cellphys::cli {

namespace {

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) { g_signal.store(sig); }

}  // namespace

void catch_interrupts() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

int interrupt_signal() { return g_signal.load(); }

}  // namespace cellphys::cli
