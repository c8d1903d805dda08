#include "tools/run_options.h"

#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <utility>

#include <CLI/CLI.hpp>

#include "runtime/ppe/settings.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/krylov.h"
#include "tools/option_values.h"
#include "tools/usage_error.h"

namespace cellphys::cli {

namespace {

// printf format: the integrators, the solvers and the workers' limit come from their tables.
const char kRunHelpFormat[] =
    "usage: cellphys run [SCENE] [options]\n"
    "       cellphys run --resume SNAPSHOT [options]\n"
    "\n"
    "Steps SCENE (a scene file, or the name of a built-in scene: `cellphys scenes` lists them;\n"
    "default: world1000), or the world saved in SNAPSHOT, and prints a summary.\n"
    "\n"
    "options:\n"
    "  --duration S      simulate S seconds (default 5)\n"
    "  --steps N         or exactly N steps\n"
    "  --dt H            step size in seconds (overrides the scene's settings.dt)\n"
    "  --integrator NAME %s\n"
    "  --solver NAME     %s\n"
    "  --tolerance T     linear solver tolerance\n"
    "  --workers K       compute workers (threads), 1 to %d\n"
    "  --out FILE        trajectory CSV: step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz\n"
    "                    (every body; step 0 and every N-th step)\n"
    "  --every N         with --out: write every N-th step (default 1)\n"
    "  --stats FILE      run statistics as JSON\n"
    "  --events FILE     contact and sensor events CSV (docs/events.md): step,t,event,a,b,\n"
    "                    px,py,pz,nx,ny,nz,approach_speed,impulse; event is touch_begin,\n"
    "                    touch_end, sensor_begin or sensor_end\n"
    "  --save-snapshot FILE  the world at the end as a snapshot (docs/distributed.md), for\n"
    "                    --resume; a resumed run steps on bit for bit\n"
    "  --snapshot-every N    with --save-snapshot: also every N-th step, a checkpoint (the file\n"
    "                    is replaced whole each time; scripts/mpi-survive restarts from it)\n"
    "  --resume FILE     start from a snapshot instead of a scene (--duration and --steps count\n"
    "                    from there; --dt, --integrator, ... change its saved settings)\n"
    "  --mpi             compute islands on MPI ranks (run under mpirun): rank 0 dispatches,\n"
    "                    the other ranks are stateless compute nodes (docs/distributed.md)\n"
    "  --mpi-deadline MS drop a compute node silent this long with islands outstanding, and\n"
    "                    wait no longer for the nodes to stop at the end (default 5000)\n"
    "  --mpi-fault F     test hook: corrupt:N (node 1 damages its N-th reply), silent:N (the\n"
    "                    last node stops answering after N islands), hang:N (it stops\n"
    "                    reading anything after N islands, as a hung process) or kill:N (it\n"
    "                    SIGKILLs itself after N islands, as a process that dies)\n"
    "  -h, --help        this text\n"
    "\n"
    "Exit codes: 0 done, 1 a failure while running or writing, 2 a usage, scene or snapshot\n"
    "error, 3 (--mpi) the run is done and written but a compute node did not stop, so the\n"
    "job was aborted.\n"
    "Built-in scenes are looked up in $CELLPHYS_SCENES, then in the source tree's examples/scenes.\n";

}  // namespace

std::string run_help() {
  const std::string integrators = spu::integrator_names(), solvers = spu::solver_names();
  const int n = std::snprintf(nullptr, 0, kRunHelpFormat, integrators.c_str(), solvers.c_str(), ppe::kMaxWorkers);
  std::string text(static_cast<size_t>(n) + 1, '\0');
  std::snprintf(text.data(), text.size(), kRunHelpFormat, integrators.c_str(), solvers.c_str(), ppe::kMaxWorkers);
  text.resize(static_cast<size_t>(n));
  return text;
}

namespace {

namespace fs = std::filesystem;

constexpr long long kMaxCount = 1000000000LL;

// The file a path names, to tell two output paths that name one file (`a` and `./a`: made
// absolute first, as weakly_canonical keeps a path relative when none of it exists).
fs::path resolved(const std::string& p, std::error_code& ec) {
  const fs::path abs = fs::absolute(p, ec);
  return ec ? fs::path() : fs::weakly_canonical(abs, ec);
}

// CLI11 splits the arguments into options, values and the scene; each value is checked here as it
// is met (so the first bad one is the one reported), with a message naming the option and what it
// takes, and unknown options and a second scene are told in this command's words.
class Parser {
 public:
  explicit Parser(RunOptions& o) : o_(o) {
    app_.set_help_flag();  // the help is run_help(), not CLI11's own
    app_.allow_extras();   // unknown options and a second scene are left in remaining(), told below
    app_.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    app_.add_flag_callback("-h,--help", [] { throw CLI::CallForHelp(); })->trigger_on_parse();
    positive("--duration", o.duration);
    count("--steps", o.steps, 0, kMaxCount);
    positive("--dt", o.dt);
    text("--integrator", o.integrator);
    text("--solver", o.solver);
    positive("--tolerance", o.tolerance);
    count("--workers", o.workers, 1, ppe::kMaxWorkers);
    text("--out", o.out);
    count("--every", o.every, 1, kMaxCount);
    text("--stats", o.stats);
    text("--events", o.events);
    text("--save-snapshot", o.save_snapshot);
    count("--snapshot-every", o.snapshot_every, 1, kMaxCount);
    value("--resume", [&o](const std::string& f) {
      if (f.empty()) throw UsageError{"--resume needs a file"};
      o.resume = f;
    });
    app_.add_flag("--mpi", o.mpi);
    positive("--mpi-deadline", o.mpi_deadline_ms);
    value("--mpi-fault", [&o](const std::string& f) {
      const size_t colon = f.find(':');
      const std::string kind = f.substr(0, colon);
      int* hook = kind == "corrupt" ? &o.mpi_corrupt
                  : kind == "silent"  ? &o.mpi_silent
                  : kind == "hang"    ? &o.mpi_hang
                  : kind == "kill"    ? &o.mpi_kill
                                      : nullptr;
      if (colon == std::string::npos || !hook)
        throw UsageError{"--mpi-fault takes corrupt:N, silent:N, hang:N or kill:N, got '" + f + "'"};
      *hook = static_cast<int>(parse_count("--mpi-fault", f.substr(colon + 1), 0, kMaxCount));
    });
    app_.add_option("scene", o.scene);
  }

  // Returns false when --help was asked for.
  bool parse(int argc, char** argv) {
    try {
      app_.parse(argc, argv);
    } catch (const CLI::CallForHelp&) {
      return false;
    } catch (const CLI::ArgumentMismatch& e) {
      // An option that takes a value came last without one (`--steps` or `--steps=`).
      const std::string last = argv[argc - 1];
      const std::string name = last.substr(0, last.find('='));
      const CLI::Option* opt = app_.get_option_no_throw(name);
      if (opt && opt->get_expected_min() > 0) throw UsageError{name + " needs a value"};
      throw UsageError{e.what()};
    } catch (const CLI::ParseError& e) {
      throw UsageError{e.what()};
    }
    for (const std::string& a : app_.remaining()) {
      if (a == "--") continue;  // the end of options, kept by allow_extras
      if (a.size() > 1 && a[0] == '-') throw UsageError{"unknown option '" + a.substr(0, a.find('=')) + "'"};
      throw UsageError{"more than one scene given ('" + o_.scene + "' and '" + a + "')"};
    }
    return true;
  }

 private:
  void value(const char* name, std::function<void(const std::string&)> set) {
    app_.add_option_function<std::string>(name, std::move(set))->trigger_on_parse();
  }
  void text(const char* name, std::string& to) {
    value(name, [&to](const std::string& v) { to = v; });
  }
  void positive(const char* name, double& to) {
    value(name, [name, &to](const std::string& v) { to = parse_positive(name, v); });
  }
  template <class Int>
  void count(const char* name, Int& to, long long lo, long long hi) {
    value(name, [name, &to, lo, hi](const std::string& v) { to = static_cast<Int>(parse_count(name, v, lo, hi)); });
  }

  RunOptions& o_;
  CLI::App app_;
};

}  // namespace

bool parse_run_options(int argc, char** argv, RunOptions& o) {
  if (!Parser(o).parse(argc, argv)) return false;
  if (o.duration > 0 && o.steps >= 0) throw UsageError{"give --duration or --steps, not both"};
  if (!o.resume.empty() && !o.scene.empty())
    throw UsageError{"give a scene or --resume SNAPSHOT, not both ('" + o.scene + "' and '" + o.resume + "')"};
  if (o.snapshot_every > 0 && o.save_snapshot.empty()) throw UsageError{"--snapshot-every needs --save-snapshot FILE"};
  const std::pair<const char*, const std::string*> outputs[] = {
      {"--out", &o.out}, {"--stats", &o.stats}, {"--save-snapshot", &o.save_snapshot}, {"--events", &o.events}};
  constexpr size_t n = std::size(outputs);
  for (size_t i = 0; i < n; ++i)
    for (size_t k = i + 1; k < n; ++k) {
      const std::string& x = *outputs[i].second;
      const std::string& y = *outputs[k].second;
      if (x.empty() || y.empty()) continue;
      std::error_code e1, e2;
      const fs::path a = resolved(x, e1), b = resolved(y, e2);
      if (x == y || (!e1 && !e2 && a == b))
        throw UsageError{std::string(outputs[i].first) + " and " + outputs[k].first + " name the same file"};
    }
  return true;
}

}  // namespace cellphys::cli
