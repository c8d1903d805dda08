// `cellphys run`'s options: what they hold, their help text, and the parser.
#pragma once
#include <string>

namespace cellphys::cli {

struct RunOptions {
  std::string scene;     // empty: the default scene
  double duration = -1;  // s; < 0: not given
  long long steps = -1;  // < 0: not given
  double dt = -1;
  std::string integrator, solver;
  double tolerance = -1;
  int workers = 0;
  std::string out, stats, events;
  long long every = 1;
  std::string save_snapshot, resume;
  long long snapshot_every = 0;
  bool mpi = false;
  double mpi_deadline_ms = 5000;
  int mpi_corrupt = -1, mpi_silent = -1, mpi_hang = -1, mpi_kill = -1;
};

/// The help text of `cellphys run`.
std::string run_help();

// Parses argv[1..argc) into `o` (argv[0] is the subcommand's name); returns false when --help
// was asked for. Throws UsageError naming the option, for a bad option or value and for options
// that do not go together.
bool parse_run_options(int argc, char** argv, RunOptions& o);

}  // namespace cellphys::cli
