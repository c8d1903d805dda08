// `cellphys replay FILE`: re-runs a recording of `cellphys serve --record` (server/replay.h) and
// checks the state hash at every recorded step.
#include <cstdio>
#include <string>

#include "server/replay.h"
#include "tools/cli.h"

namespace cellphys::cli {

namespace {

const char kReplayHelp[] =
    "usage: cellphys replay FILE\n"
    "\n"
    "Re-runs a recording made by `cellphys serve --record FILE`: the world's starting snapshot,\n"
    "every command at the step it was applied, and the state hash after every step compared with\n"
    "the recording's. Prints the steps, commands and the final state hash.\n"
    "\n"
    "Exit codes: 0 every hash matched, 1 one differed (the step is printed), 2 not a readable\n"
    "recording. A recording cut short (the server was killed) is replayed up to its last whole\n"
    "record, with a warning.\n";

}  // namespace

int replay_main(int argc, char** argv) {
  std::string file;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::fputs(kReplayHelp, stdout);
      return 0;
    }
    if ((!a.empty() && a[0] == '-') || !file.empty()) {
      std::fprintf(stderr, "cellphys replay: unexpected argument '%s'\n(`cellphys replay --help`)\n", a.c_str());
      return 2;
    }
    file = a;
  }
  if (file.empty()) {
    std::fprintf(stderr, "cellphys replay: which recording? (`cellphys replay --help`)\n");
    return 2;
  }
  server::Recording rec;
  try {
    rec = server::read_recording(file);
  } catch (const server::RecordingError& e) {
    std::fprintf(stderr, "cellphys replay: %s\n", e.what());
    return 2;
  }
  if (!rec.damage.empty())
    std::fprintf(stderr, "cellphys replay: warning: %s: %s; replaying what comes before it\n", file.c_str(),
                 rec.damage.c_str());
  else if (!rec.ended)
    std::fprintf(stderr, "cellphys replay: warning: %s has no end record (the server did not stop cleanly)\n",
                 file.c_str());
  server::ReplayResult r;
  try {
    r = server::replay(rec);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cellphys replay: %s: %s\n", file.c_str(), e.what());
    return 2;
  }
  if (!r.refused.empty()) {
    std::fprintf(stderr, "cellphys replay: %s: %s\n", file.c_str(), r.refused.c_str());
    return 1;
  }
  if (!r.matched) {
    std::fprintf(stderr, "cellphys replay: %s: the state hash differs at step %llu: recorded 0x%016llx, replayed 0x%016llx\n",
                 file.c_str(), static_cast<unsigned long long>(r.mismatch_step),
                 static_cast<unsigned long long>(r.recorded_hash), static_cast<unsigned long long>(r.replayed_hash));
    return 1;
  }
  std::printf("world %s: %llu steps, %llu commands, %llu state hashes matched\nstep %llu\nstate hash 0x%016llx\n",
              rec.world.c_str(), static_cast<unsigned long long>(r.steps), static_cast<unsigned long long>(r.commands),
              static_cast<unsigned long long>(r.hashes_checked), static_cast<unsigned long long>(r.final_step),
              static_cast<unsigned long long>(r.final_hash));
  return 0;
}

}  // namespace cellphys::cli
