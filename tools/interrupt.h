// SIGINT and SIGTERM during a run: noted rather than fatal, so that the step loop stops between
// steps and the run's output files are removed on the way out instead of left half written.
#pragma once

namespace cellphys::cli {

// Installs the handlers (for the rest of the process).
void catch_interrupts();

// The signal that asked the run to stop, or 0.
int interrupt_signal();

}  // namespace cellphys::cli
