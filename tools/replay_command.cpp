// `cellphys replay FILE`: re-runs a recording of `cellphys serve --record` (server/replay.h),
// checks the state hash at every recorded step and every recorded frame byte for byte, and
// writes the replayed trajectory with --out.
#include <cstdio>
#include <string>

#include "server/replay.h"
#include "tools/atomic_file.h"
#include "tools/cli.h"
#include "tools/option_values.h"
#include "tools/trajectory_csv.h"
#include "tools/usage_error.h"

namespace cellphys::cli {

namespace {

const char kReplayHelp[] =
    "usage: cellphys replay FILE [--out CSV [--every N]]\n"
    "\n"
    "Re-runs a recording made by `cellphys serve --record FILE`: the world's starting snapshot,\n"
    "every command at the step it was applied, the state hash after every step compared with\n"
    "the recording's, and each recorded frame (the state messages the server sent, unless it ran\n"
    "with --record-frames off) compared byte for byte with the replayed world's, but for the\n"
    "server's wall times. Prints the steps, commands, hashes and frames checked and the final\n"
    "state hash.\n"
    "\n"
    "options:\n"
    "  --out CSV     the replayed trajectory, as `cellphys run --out` writes it (body: its id)\n"
    "  --every N     with --out: step 0 and every N-th step (default 1)\n"
    "\n"
    "Exit codes: 0 every hash and frame matched, 1 one differed (the step and where are printed),\n"
    "2 not a readable recording or a usage error. A recording cut short (the server was killed)\n"
    "is replayed up to its last whole record, with a warning.\n";

struct ReplayOptions {
  std::string file, out;
  long long every = 1;
};

/// false when --help was asked for; throws UsageError.
bool parse_replay_options(int argc, char** argv, ReplayOptions& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") return false;
    if (a == "--out" || a == "--every") {
      if (i + 1 >= argc) throw UsageError{a + " needs a value"};
      const std::string v = argv[++i];
      if (a == "--out") {
        if (v.empty()) throw UsageError{"--out needs a file"};
        o.out = v;
      } else {
        o.every = parse_count(a, v, 1, 1000000000LL);
      }
      continue;
    }
    if ((!a.empty() && a[0] == '-') || !o.file.empty()) throw UsageError{"unexpected argument '" + a + "'"};
    o.file = a;
  }
  if (o.file.empty()) throw UsageError{"which recording?"};
  return true;
}

}  // namespace

int replay_main(int argc, char** argv) {
  ReplayOptions o;
  try {
    if (!parse_replay_options(argc, argv, o)) {
      std::fputs(kReplayHelp, stdout);
      return 0;
    }
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cellphys replay: %s\n(`cellphys replay --help`)\n", e.message.c_str());
    return 2;
  }
  const std::string& file = o.file;
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
  AtomicFile out;
  std::vector<ppe::BodyId> bodies;
  std::vector<std::string> ids;
  auto write_rows = [&](const ppe::World& w) {
    const uint64_t step = w.last_stats().step;
    if (step % static_cast<uint64_t>(o.every) != 0) return;
    bodies = w.bodies();  // spawned and removed bodies come and go
    ids.resize(bodies.size());
    for (size_t i = 0; i < bodies.size(); ++i) ids[i] = std::to_string(bodies[i]);
    write_trajectory_rows(out.get(), w, bodies, step, double(step) * w.settings().dt, ids);
  };
  server::ReplayResult r;
  try {
    if (!o.out.empty()) {
      out.open(o.out);
      write_trajectory_header(out.get());
    }
    r = server::replay(rec, o.out.empty() ? std::function<void(const ppe::World&)>{} : write_rows);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cellphys replay: %s: %s\n", file.c_str(), e.what());
    return 2;
  }
  if (!r.refused.empty()) {
    std::fprintf(stderr, "cellphys replay: %s: %s\n", file.c_str(), r.refused.c_str());
    return 1;
  }
  if (!r.matched && !r.frame_difference.empty()) {
    std::fprintf(stderr, "cellphys replay: %s: the frame at step %llu differs from the recorded one: %s\n", file.c_str(),
                 static_cast<unsigned long long>(r.mismatch_step), r.frame_difference.c_str());
    return 1;
  }
  if (!r.matched) {
    std::fprintf(stderr, "cellphys replay: %s: the state hash differs at step %llu: recorded 0x%016llx, replayed 0x%016llx\n",
                 file.c_str(), static_cast<unsigned long long>(r.mismatch_step),
                 static_cast<unsigned long long>(r.recorded_hash), static_cast<unsigned long long>(r.replayed_hash));
    return 1;
  }
  try {
    if (out.is_open()) out.commit();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cellphys replay: %s\n", e.what());
    return 2;
  }
  const std::string frames =
      rec.frames ? std::to_string(r.frames_checked) + " frames and " + std::to_string(r.stages_checked) + " stages" +
                       (rec.debug ? " and " + std::to_string(r.debug_checked) + " debug messages" : std::string()) + " matched"
      : rec.version < 2 ? "no frames (a version-1 recording)"
                        : "no frames (recorded with --record-frames off)";
  std::printf("world %s: %llu steps, %llu commands, %llu state hashes matched, %s\nstep %llu\nstate hash 0x%016llx\n",
              rec.world.c_str(), static_cast<unsigned long long>(r.steps), static_cast<unsigned long long>(r.commands),
              static_cast<unsigned long long>(r.hashes_checked), frames.c_str(),
              static_cast<unsigned long long>(r.final_step), static_cast<unsigned long long>(r.final_hash));
  return 0;
}

}  // namespace cellphys::cli
