// What a run did, told two ways: the summary `cellphys run` prints on stdout, and the
// statistics JSON of --stats (its keys and their order are read by tests and scripts).
#pragma once
#include <string>

#include "tools/run_options.h"
#include "tools/run_totals.h"
#include "tools/run_world.h"

namespace cellphys::cli {

struct RunOutcome {
  long long steps = 0;
  double wall_s = 0;
  double kinetic_energy_initial = 0, kinetic_energy_final = 0;
  RunTotals totals{0};
  const char* runner = nullptr;  // the island runner's name; null: the in-process worker threads
};

// The JSON text, ending in a newline.
std::string stats_json(const RunOptions& o, const RunWorld& w, const RunOutcome& r);

void print_summary(const RunOptions& o, const RunWorld& w, const RunOutcome& r);

}  // namespace cellphys::cli
