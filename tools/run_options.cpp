#include "tools/run_options.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <utility>

#include "tools/usage_error.h"

namespace cellphys::cli {

const char kRunHelp[] =
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
    "  --integrator NAME implicit_split, implicit_euler, rosenbrock, symplectic_euler,\n"
    "                    explicit_euler, rk4\n"
    "  --solver NAME     cgs, bicgstab, direct\n"
    "  --tolerance T     linear solver tolerance\n"
    "  --workers K       compute workers (threads)\n"
    "  --out FILE        trajectory CSV: step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz\n"
    "                    (every body; step 0 and every N-th step)\n"
    "  --every N         with --out: write every N-th step (default 1)\n"
    "  --stats FILE      run statistics as JSON\n"
    "  --save-snapshot FILE  the world at the end as a snapshot (docs/distributed.md), for\n"
    "                    --resume; a resumed run steps on bit for bit\n"
    "  --snapshot-every N    with --save-snapshot: also every N-th step (the file is replaced\n"
    "                    whole each time)\n"
    "  --resume FILE     start from a snapshot instead of a scene (--duration and --steps count\n"
    "                    from there; --dt, --integrator, ... change its saved settings)\n"
    "  --mpi             compute islands on MPI ranks (run under mpirun): rank 0 dispatches,\n"
    "                    the other ranks are stateless compute nodes (docs/distributed.md)\n"
    "  --mpi-deadline MS drop a compute node silent this long with islands outstanding\n"
    "                    (default 5000)\n"
    "  --mpi-fault F     test hook: corrupt:N (node 1 damages its N-th reply) or silent:N\n"
    "                    (the last node stops answering after N islands)\n"
    "  -h, --help        this text\n"
    "\n"
    "Exit codes: 0 done, 1 a failure while running or writing, 2 a usage, scene or snapshot\n"
    "error.\n"
    "Built-in scenes are looked up in $CELLPHYS_SCENES, then in the source tree's examples/scenes.\n";

namespace {

namespace fs = std::filesystem;

double parse_positive(const std::string& opt, const char* text) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || errno == ERANGE || !std::isfinite(v) || !(v > 0))
    throw UsageError{opt + " needs a positive number, got '" + std::string(text) + "'"};
  return v;
}

long long parse_count(const std::string& opt, const char* text, long long lo, long long hi) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text, &end, 10);
  if (end == text || *end != '\0' || errno == ERANGE || v < lo || v > hi)
    throw UsageError{opt + " needs an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got '" +
                     std::string(text) + "'"};
  return v;
}

}  // namespace

bool parse_run_options(int argc, char** argv, RunOptions& o) {
  bool have_duration = false, have_steps = false;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    std::string value;
    bool has_inline = false;
    if (a.rfind("--", 0) == 0) {
      const size_t eq = a.find('=');
      if (eq != std::string::npos) {
        value = a.substr(eq + 1);
        a = a.substr(0, eq);
        has_inline = true;
      }
    }
    auto next = [&]() -> const char* {
      if (has_inline) return value.c_str();
      if (i + 1 >= argc) throw UsageError{a + " needs a value"};
      return argv[++i];
    };
    if (a == "-h" || a == "--help") return false;
    if (a == "--duration") {
      o.duration = parse_positive(a, next());
      have_duration = true;
    } else if (a == "--steps") {
      o.steps = parse_count(a, next(), 0, 1000000000LL);
      have_steps = true;
    } else if (a == "--dt") {
      o.dt = parse_positive(a, next());
    } else if (a == "--integrator") {
      o.integrator = next();
    } else if (a == "--solver") {
      o.solver = next();
    } else if (a == "--tolerance") {
      o.tolerance = parse_positive(a, next());
    } else if (a == "--workers") {
      o.workers = static_cast<int>(parse_count(a, next(), 1, 256));
    } else if (a == "--out") {
      o.out = next();
    } else if (a == "--every") {
      o.every = parse_count(a, next(), 1, 1000000000LL);
    } else if (a == "--stats") {
      o.stats = next();
    } else if (a == "--save-snapshot") {
      o.save_snapshot = next();
    } else if (a == "--snapshot-every") {
      o.snapshot_every = parse_count(a, next(), 1, 1000000000LL);
    } else if (a == "--resume") {
      o.resume = next();
      if (o.resume.empty()) throw UsageError{"--resume needs a file"};
    } else if (a == "--mpi") {
      o.mpi = true;
    } else if (a == "--mpi-deadline") {
      o.mpi_deadline_ms = parse_positive(a, next());
    } else if (a == "--mpi-fault") {
      const std::string f = next();
      const size_t colon = f.find(':');
      const std::string kind = f.substr(0, colon);
      if (colon == std::string::npos || (kind != "corrupt" && kind != "silent"))
        throw UsageError{"--mpi-fault takes corrupt:N or silent:N, got '" + f + "'"};
      const int n = static_cast<int>(parse_count(a, f.c_str() + colon + 1, 0, 1000000000LL));
      (kind == "corrupt" ? o.mpi_corrupt : o.mpi_silent) = n;
    } else if (!a.empty() && a[0] == '-' && a != "-") {
      throw UsageError{"unknown option '" + a + "'"};
    } else if (o.scene.empty()) {
      o.scene = a;
    } else {
      throw UsageError{"more than one scene given ('" + o.scene + "' and '" + a + "')"};
    }
  }
  if (have_duration && have_steps) throw UsageError{"give --duration or --steps, not both"};
  if (!o.resume.empty() && !o.scene.empty())
    throw UsageError{"give a scene or --resume SNAPSHOT, not both ('" + o.scene + "' and '" + o.resume + "')"};
  if (o.snapshot_every > 0 && o.save_snapshot.empty()) throw UsageError{"--snapshot-every needs --save-snapshot FILE"};
  const std::pair<const char*, const std::string*> outputs[] = {
      {"--out", &o.out}, {"--stats", &o.stats}, {"--save-snapshot", &o.save_snapshot}};
  for (size_t i = 0; i < 3; ++i)
    for (size_t k = i + 1; k < 3; ++k) {
      const std::string& x = *outputs[i].second;
      const std::string& y = *outputs[k].second;
      if (x.empty() || y.empty()) continue;
      std::error_code e1, e2;
      const fs::path a = fs::weakly_canonical(x, e1), b = fs::weakly_canonical(y, e2);
      if (x == y || (!e1 && !e2 && a == b))
        throw UsageError{std::string(outputs[i].first) + " and " + outputs[k].first + " name the same file"};
    }
  return true;
}

}  // namespace cellphys::cli
