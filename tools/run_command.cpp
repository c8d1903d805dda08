// `cellphys run` and `cellphys scenes`: load a scene (a file or a built-in name) or resume a
// snapshot, step the world, and report: a summary on stdout, optionally a trajectory CSV, a
// statistics JSON and a snapshot of the world. Output files are written under a temporary name in the same directory and
// renamed at the end, so a failed or interrupted run never leaves a partial file.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/settings.h"
#include "runtime/scene/scene.h"
#include "runtime/spu/simd.h"
#include "tools/cli.h"
#ifdef CELLPHYS_HAVE_MPI
#include "runtime/ppe/mpi_runner.h"
#endif

#ifndef CELLPHYS_SCENES_DIR
#define CELLPHYS_SCENES_DIR ""
#endif

namespace cellphys::cli {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const char kDefaultScene[] = "world1000";
constexpr double kDefaultDuration = 5.0;  // s of simulated time when neither --duration nor --steps

// printf format: the integrators, the solvers and the workers' limit come from their tables.
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
    "  --integrator NAME %s\n"
    "  --solver NAME     %s\n"
    "  --tolerance T     linear solver tolerance\n"
    "  --workers K       compute workers (threads), 1 to %d\n"
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

struct UsageError {
  std::string message;
};

// A snapshot that cannot be resumed (missing, unreadable, damaged): exit code 2.
struct SnapshotError {
  std::string message;
};

// ---- interruption: SIGINT/SIGTERM stop the run between steps so temporaries are removed ----

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) { g_signal.store(sig); }

// ---- output files: temporary name, renamed on success, removed otherwise ----

class AtomicFile {
 public:
  AtomicFile() = default;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile() { discard(); }

  // Opens a temporary next to `path`; throws std::runtime_error with the reason.
  void open(const std::string& path) {
    path_ = path;
    const fs::path p(path);
    const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
    std::string name = "." + p.filename().string() + ".tmp." + std::to_string(::getpid()) + ".XXXXXX";
    std::string tmpl = (dir / name).string();
    std::vector<char> buf(tmpl.begin(), tmpl.end());
    buf.push_back('\0');
    const int fd = ::mkstemp(buf.data());
    if (fd < 0) throw std::runtime_error(path + ": cannot create a file next to it: " + std::strerror(errno));
    tmp_ = buf.data();
    f_ = ::fdopen(fd, "w");
    if (!f_) {
      ::close(fd);
      discard();
      throw std::runtime_error(path + ": cannot open: " + std::strerror(errno));
    }
    std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
  }
  FILE* get() const { return f_; }
  bool is_open() const { return f_ != nullptr; }

  void commit() {
    if (!f_) return;
    const bool write_ok = !std::ferror(f_);
    const bool close_ok = std::fclose(f_) == 0;
    f_ = nullptr;
    if (!write_ok || !close_ok) {
      const std::string why = std::strerror(errno);
      discard();
      throw std::runtime_error(path_ + ": write error: " + why);
    }
    // mkstemp made it 0600; give it the usual permissions
    const mode_t mask = ::umask(0);
    ::umask(mask);
    ::chmod(tmp_.c_str(), 0666 & ~mask);
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
      const std::string why = std::strerror(errno);
      discard();
      throw std::runtime_error(path_ + ": cannot rename the finished file into place: " + why);
    }
    tmp_.clear();
  }
  void discard() {
    if (f_) std::fclose(f_);
    f_ = nullptr;
    if (!tmp_.empty()) std::remove(tmp_.c_str());
    tmp_.clear();
  }

 private:
  std::string path_, tmp_;
  FILE* f_ = nullptr;
};

// ---- arguments ----

struct Options {
  std::string scene;
  double duration = -1;
  long long steps = -1;
  double dt = -1;
  std::string integrator, solver;
  double tolerance = -1;
  int workers = 0;
  std::string out, stats;
  long long every = 1;
  std::string save_snapshot, resume;
  long long snapshot_every = 0;
  bool mpi = false;
  double mpi_deadline_ms = 5000;
  int mpi_corrupt = -1, mpi_silent = -1;
};

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

// Returns false when --help was asked for.
bool parse_options(int argc, char** argv, Options& o) {
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
      o.workers = static_cast<int>(parse_count(a, next(), 1, ppe::kMaxWorkers));
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

// ---- built-in scenes ----

std::string exe_dir() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : p.parent_path().string();
}

// Directories searched for built-in scenes, in order.
std::vector<std::string> scene_dirs() {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("CELLPHYS_SCENES"); env && *env) {
    dirs.push_back(env);
    return dirs;  // an explicit override is the only place looked at
  }
  const std::string exe = exe_dir();
  if (!exe.empty()) {
    dirs.push_back(exe + "/scenes");                         // an installed layout
    dirs.push_back((fs::path(exe) / "../../../examples/scenes").lexically_normal().string());  // build/<preset>/tools/
  }
  if (*CELLPHYS_SCENES_DIR) dirs.push_back(CELLPHYS_SCENES_DIR);  // the source tree it was built from
  return dirs;
}

struct BuiltinScene {
  std::string name, path;
};

std::vector<BuiltinScene> builtin_scenes() {
  for (const std::string& d : scene_dirs()) {
    std::error_code ec;
    if (!fs::is_directory(d, ec)) continue;
    std::vector<BuiltinScene> out;
    for (const auto& e : fs::directory_iterator(d, ec))
      if (e.path().extension() == ".json") out.push_back({e.path().stem().string(), e.path().string()});
    if (out.empty()) continue;
    std::sort(out.begin(), out.end(), [](const BuiltinScene& a, const BuiltinScene& b) {
      // the default world first, then by name
      if ((a.name == kDefaultScene) != (b.name == kDefaultScene)) return a.name == kDefaultScene;
      return a.name < b.name;
    });
    return out;
  }
  return {};
}

bool looks_like_path(const std::string& s) {
  return s.find('/') != std::string::npos || (s.size() > 5 && s.compare(s.size() - 5, 5, ".json") == 0);
}

// The file a SCENE argument names (a path, or a built-in scene's file); throws UsageError.
std::string resolve_scene(const std::string& arg) {
  std::error_code ec;
  if (looks_like_path(arg) || fs::is_regular_file(arg, ec)) return arg;
  const std::vector<BuiltinScene> all = builtin_scenes();
  for (const BuiltinScene& b : all)
    if (b.name == arg) return b.path;
  std::string names;
  for (const BuiltinScene& b : all) names += (names.empty() ? "" : ", ") + b.name;
  if (names.empty()) {
    std::string where;
    for (const std::string& d : scene_dirs()) where += (where.empty() ? "" : ", ") + d;
    throw UsageError{"unknown scene '" + arg + "': no built-in scenes found (looked in " + where +
                     "; set CELLPHYS_SCENES)"};
  }
  throw UsageError{"unknown scene '" + arg + "' (not a file; built-in scenes: " + names + ")"};
}

// ---- output formatting ----

void put_float(std::string& line, float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  line.append(buf, r.ptr);
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

void write_rows(FILE* f, const ppe::World& world, const std::vector<ppe::BodyId>& bodies, uint64_t step, double t,
                const std::vector<std::string>& ids) {
  std::string line;
  line.reserve(256);
  char head[64];
  const int n = std::snprintf(head, sizeof head, "%llu,%.9g,", static_cast<unsigned long long>(step), t);
  for (size_t i = 0; i < bodies.size(); ++i) {
    const ppe::BodyState s = world.state(bodies[i]);
    line.assign(head, static_cast<size_t>(n));
    line += ids[i];
    for (float v : s.position) line += ',', put_float(line, v);
    for (float v : s.orientation) line += ',', put_float(line, v);
    for (float v : s.velocity) line += ',', put_float(line, v);
    for (float v : s.angular_velocity) line += ',', put_float(line, v);
    line += '\n';
    std::fwrite(line.data(), 1, line.size(), f);
  }
}

// A progress bar on stderr for runs longer than a second, when stderr is a terminal.
class Progress {
 public:
  explicit Progress(long long total) : total_(total), enabled_(::isatty(2) == 1), start_(Clock::now()) {}
  void update(long long done) {
    if (!enabled_ || total_ <= 0) return;
    const auto now = Clock::now();
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    if (elapsed < 1.0 || std::chrono::duration<double>(now - last_).count() < 0.1) return;
    last_ = now;
    const double frac = double(done) / double(total_);
    const int width = 30, fill = static_cast<int>(frac * width);
    const double eta = done > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
    std::fprintf(stderr, "\r[%.*s%.*s] %3d%% step %lld/%lld, %.0f s left ", fill,
                 "##############################", width - fill, "..............................",
                 static_cast<int>(100 * frac), done, total_, eta);
    std::fflush(stderr);
    shown_ = true;
  }
  void finish() {
    if (shown_) std::fprintf(stderr, "\r\033[K");
    shown_ = false;
  }
  ~Progress() { finish(); }

 private:
  long long total_;
  bool enabled_, shown_ = false;
  Clock::time_point start_, last_{};
};

std::string scene_label(const std::string& arg, const std::string& file) {
  return arg == file ? file : arg + " (" + file + ")";
}

// The world a run steps: built from a scene, or restored from a snapshot.
struct Loaded {
  std::string arg, file, description;
  std::unique_ptr<ppe::World> world;
  std::vector<ppe::BodyId> bodies;
  std::vector<std::string> ids;  // CSV body column, in `bodies` order
  long long forces = -1;         // unknown for a snapshot
  bool resumed = false;
};

std::vector<unsigned char> read_snapshot_file(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw SnapshotError{path + ": no such snapshot"};
  if (fs::is_directory(path, ec)) throw SnapshotError{path + ": is a directory, not a snapshot"};
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw SnapshotError{path + ": cannot open: " + std::strerror(errno)};
  std::vector<unsigned char> bytes;
  unsigned char buf[1 << 16];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) bytes.insert(bytes.end(), buf, buf + n);
  const bool bad = std::ferror(f) != 0;
  std::fclose(f);
  if (bad) throw SnapshotError{path + ": read error"};
  return bytes;
}

// Applies the command line's overrides to settings (a scene's or a snapshot's).
void apply_overrides(const Options& o, ppe::WorldSettings& s) {
  if (o.dt > 0) s.dt = static_cast<float>(o.dt);
  if (!o.integrator.empty() && !spu::parse_integrator(o.integrator, &s.integrator))
    throw UsageError{"unknown integrator '" + o.integrator + "' (known: " + spu::integrator_names() + ")"};
  if (!o.solver.empty() && !spu::parse_solver(o.solver, &s.solver))
    throw UsageError{"unknown solver '" + o.solver + "' (known: " + spu::solver_names() + ")"};
  if (o.tolerance > 0) s.tolerance = static_cast<float>(o.tolerance);
  if (o.workers > 0) s.workers = o.workers;
  if (!(s.dt > 0.0f) || !std::isfinite(s.dt)) throw UsageError{"--dt is too small or too large"};
}

Loaded load(const Options& o) {
  Loaded l;
  if (!o.resume.empty()) {
    l.arg = l.file = o.resume;
    l.resumed = true;
    const std::vector<unsigned char> bytes = read_snapshot_file(o.resume);
    try {
      l.world = ppe::World::restore(bytes.data(), bytes.size());
    } catch (const ppe::WorldError& e) {
      throw SnapshotError{o.resume + ": not a snapshot this cellphys can resume: " + e.what()};
    }
    ppe::WorldSettings s = l.world->settings();
    apply_overrides(o, s);
    try {
      l.world->set_settings(s);
    } catch (const ppe::WorldError& e) {
      throw UsageError{e.what()};
    }
    l.bodies = l.world->bodies();
    for (ppe::BodyId id : l.bodies) l.ids.push_back(std::to_string(id));  // a snapshot keeps no scene ids
    return l;
  }
  l.arg = o.scene.empty() ? kDefaultScene : o.scene;
  l.file = resolve_scene(l.arg);
  scene::SceneDesc desc = scene::load_scene(l.file);
  apply_overrides(o, desc.settings);
  scene::BuiltScene built = scene::build_world(desc);
  for (const std::string& w : built.warnings) std::fprintf(stderr, "cellphys: warning: %s\n", w.c_str());
  l.description = desc.description;
  l.world = std::move(built.world);
  l.bodies = built.bodies;
  l.forces = static_cast<long long>(built.forces.size());
  for (const scene::BodySpec& b : desc.bodies) l.ids.push_back(csv_field(b.id));
  return l;
}

// Writes the world's snapshot to `path` under a temporary name, then renames it into place.
void save_snapshot(const ppe::World& world, const std::string& path) {
  const std::vector<unsigned char> bytes = world.snapshot();
  AtomicFile f;
  f.open(path);
  std::fwrite(bytes.data(), 1, bytes.size(), f.get());
  f.commit();
}

int run(const Options& o, std::shared_ptr<ppe::IslandRunner> runner) {
  Loaded loaded = load(o);
  const std::string& arg = loaded.arg;
  const std::string& file = loaded.file;
  ppe::World& world = *loaded.world;
  const ppe::WorldSettings& settings = world.settings();
  if (runner) world.set_runner(runner);

  const double dt = settings.dt;
  long long steps = o.steps;
  if (steps < 0) {
    const double duration = o.duration > 0 ? o.duration : kDefaultDuration;
    const double n = std::ceil(duration / dt - 1e-9);
    if (!(n <= 1e9)) throw UsageError{"--duration / dt is more than 1e9 steps"};  // before the cast
    steps = static_cast<long long>(n);
  }

  AtomicFile out, stats_file;
  const std::vector<std::string>& ids = loaded.ids;
  if (!o.out.empty()) {
    out.open(o.out);
    std::fputs("step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz\n", out.get());
    write_rows(out.get(), world, loaded.bodies, 0, 0.0, ids);
  }
  if (!o.stats.empty()) stats_file.open(o.stats);

  const double ke0 = world.kinetic_energy();
  std::vector<double> step_ms;
  step_ms.reserve(static_cast<size_t>(std::min<long long>(steps, 10000000)));
  uint64_t iterations = 0, solves = 0, halvings = 0, failed = 0, decoupled = 0, contacts_max = 0;
  ppe::StepStats wire;  // transport and wire-table totals over the run
  size_t ls_peak = 0;
  Progress progress(steps);
  const auto t0 = Clock::now();
  for (long long s = 1; s <= steps; ++s) {
    if (g_signal.load()) {
      progress.finish();
      std::fprintf(stderr, "cellphys: interrupted at step %lld of %lld; no trajectory or statistics written%s\n", s - 1,
                   steps, o.snapshot_every > 0 ? " (periodic snapshots stay)" : "");
      return 128 + g_signal.load();
    }
    const auto a = Clock::now();
    const ppe::StepStats& st = world.step();
    step_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
    iterations += st.solver_iterations;
    solves += st.solves;
    halvings += st.step_halvings;
    failed += st.failed_islands;
    decoupled += st.decoupled_islands;
    contacts_max = std::max<uint64_t>(contacts_max, st.contacts);
    wire.bytes_to_nodes += st.bytes_to_nodes;
    wire.bytes_from_nodes += st.bytes_from_nodes;
    wire.messages += st.messages;
    wire.bad_messages += st.bad_messages;
    wire.recomputed_islands += st.recomputed_islands;
    wire.reassigned_islands += st.reassigned_islands;
    wire.dropped_nodes += st.dropped_nodes;
    wire.island_bodies += st.island_bodies;
    wire.island_bytes_shared += st.island_bytes_shared;
    wire.wire_table_to_nodes += st.wire_table_to_nodes;
    wire.wire_table_to_nodes_compressed += st.wire_table_to_nodes_compressed;
    wire.wire_table_from_nodes += st.wire_table_from_nodes;
    wire.image_bytes += st.image_bytes;
    wire.result_bytes += st.result_bytes;
    ls_peak = std::max(ls_peak, st.local_store_peak_bytes);
    if (out.is_open() && s % o.every == 0)
      write_rows(out.get(), world, loaded.bodies, static_cast<uint64_t>(s), double(s) * dt, ids);
    if (o.snapshot_every > 0 && s % o.snapshot_every == 0 && s < steps) save_snapshot(world, o.save_snapshot);
    progress.update(s);
  }
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  progress.finish();
  const double ke1 = world.kinetic_energy();
  const ppe::StepStats& last = world.last_stats();

  std::vector<double> sorted = step_ms;
  std::sort(sorted.begin(), sorted.end());
  const double median = sorted.empty() ? 0.0
                        : sorted.size() % 2 ? sorted[sorted.size() / 2]
                                            : 0.5 * (sorted[sorted.size() / 2 - 1] + sorted[sorted.size() / 2]);
  uint32_t statics = 0;
  for (ppe::BodyId id : loaded.bodies) statics += world.is_static(id) ? 1 : 0;
  const uint32_t dynamic = static_cast<uint32_t>(loaded.bodies.size()) - statics;
  // Before any step, every dynamic body counts as active.
  const uint32_t active = steps > 0 ? last.active_bodies : dynamic;
  const uint32_t sleeping = steps > 0 ? last.sleeping_bodies : 0;
  const double iter_mean = solves ? double(iterations) / double(solves) : 0.0;
  char hash[32];
  std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(world.state_hash()));
  const char* runner_name = runner ? runner->name() : "threads";
  const double per_body = wire.island_bodies ? 1.0 / double(wire.island_bodies) : 0.0;

  if (stats_file.is_open()) {
    nlohmann::ordered_json j;
    j["scene"] = arg;
    j["scene_file"] = file;
    j["integrator"] = spu::integrator_name(settings.integrator);
    j["solver"] = spu::solver_name(settings.solver);
    j["dt"] = dt;
    j["workers"] = settings.workers;
    j["simd_path"] = simd::kPathName;
    j["steps"] = steps;
    j["sim_time_s"] = double(steps) * dt;
    j["wall_s"] = wall;
    j["ms_per_step_median"] = median;
    j["ms_per_step_mean"] = steps ? wall * 1000.0 / double(steps) : 0.0;
    j["ms_per_step_max"] = sorted.empty() ? 0.0 : sorted.back();
    j["bodies"] = loaded.bodies.size();
    j["static_bodies"] = statics;
    if (loaded.forces >= 0) j["forces"] = loaded.forces;
    else j["forces"] = nullptr;  // a snapshot's forces are not listed
    j["active_bodies"] = active;
    j["sleeping_bodies"] = sleeping;
    j["islands"] = last.islands;
    j["contacts"] = last.contacts;
    j["contacts_max"] = contacts_max;
    j["solver_iterations_mean"] = iter_mean;
    j["solver_iterations_total"] = iterations;
    j["solves"] = solves;
    j["step_halvings"] = halvings;
    j["failed_islands"] = failed;
    j["local_store_peak_bytes"] = ls_peak;
    j["decoupled_islands"] = decoupled;
    j["kinetic_energy_initial"] = ke0;
    j["kinetic_energy_final"] = ke1;
    j["state_hash"] = hash;
    j["runner"] = runner_name;
    if (loaded.resumed) j["resumed_from"] = o.resume;
    if (!o.save_snapshot.empty()) j["snapshot"] = o.save_snapshot;
    nlohmann::ordered_json t;
    t["island_bodies"] = wire.island_bodies;  // body records shipped, summed over steps
    t["bytes_to_nodes"] = wire.bytes_to_nodes;
    t["bytes_from_nodes"] = wire.bytes_from_nodes;
    t["bytes_to_nodes_per_body"] = double(wire.bytes_to_nodes) * per_body;
    t["bytes_from_nodes_per_body"] = double(wire.bytes_from_nodes) * per_body;
    t["messages"] = wire.messages;
    t["table_to_nodes_per_body"] = double(wire.wire_table_to_nodes) * per_body;
    t["table_to_nodes_compressed_per_body"] = double(wire.wire_table_to_nodes_compressed) * per_body;
    t["table_from_nodes_per_body"] = double(wire.wire_table_from_nodes) * per_body;
    t["shared_per_body"] = double(wire.island_bytes_shared) * per_body;
    t["image_bytes_per_body"] = double(wire.image_bytes) * per_body;
    t["result_bytes_per_body"] = double(wire.result_bytes) * per_body;
    t["bad_messages"] = wire.bad_messages;
    t["recomputed_islands"] = wire.recomputed_islands;
    t["reassigned_islands"] = wire.reassigned_islands;
    t["dropped_nodes"] = wire.dropped_nodes;
    j["transport"] = t;
    const std::string text = j.dump(2) + "\n";
    std::fwrite(text.data(), 1, text.size(), stats_file.get());
  }
  // Both files are complete; move them into place (a failure removes what is left), then the
  // snapshot, so a failed commit leaves no new snapshot either.
  if (out.is_open()) out.commit();
  if (stats_file.is_open()) stats_file.commit();
  if (!o.save_snapshot.empty()) save_snapshot(world, o.save_snapshot);

  if (loaded.resumed)
    std::printf("resumed      %s\n", file.c_str());
  else
    std::printf("scene        %s\n", scene_label(arg, file).c_str());
  if (!loaded.description.empty()) std::printf("description  %s\n", loaded.description.c_str());
  if (loaded.forces >= 0)
    std::printf("bodies       %zu (%u static), %lld forces\n", loaded.bodies.size(), statics, loaded.forces);
  else
    std::printf("bodies       %zu (%u static)\n", loaded.bodies.size(), statics);
  std::printf("settings     dt %.6g s, %s, %s, tolerance %g, %d worker%s, SIMD %s\n", dt,
              spu::integrator_name(settings.integrator), spu::solver_name(settings.solver),
              double(settings.tolerance), settings.workers, settings.workers == 1 ? "" : "s",
              simd::kPathName);
  std::printf("run          %lld steps, %.4g s simulated in %.3f s wall, median %.3f ms per step\n", steps,
              double(steps) * dt, wall, median);
  std::printf("at the end   %u active, %u sleeping, %u islands, %u contacts\n", active, sleeping, last.islands,
              last.contacts);
  std::printf("solver       %.2f iterations per solve, %llu step halvings, %llu failed islands\n", iter_mean,
              static_cast<unsigned long long>(halvings), static_cast<unsigned long long>(failed));
  std::printf("local store  peak %zu bytes, %llu decoupled islands\n", ls_peak,
              static_cast<unsigned long long>(decoupled));
  std::printf("energy       kinetic %.6g J at the start, %.6g J at the end\n", ke0, ke1);
  if (runner)
    std::printf("transport    %s: %.1f bytes per body out, %.1f back (tables: %.1f compressed, %.1f with geometry, "
                "%.1f back); %u bad messages, %u islands recomputed, %u reassigned, %u nodes dropped\n",
                runner_name, double(wire.bytes_to_nodes) * per_body, double(wire.bytes_from_nodes) * per_body,
                double(wire.wire_table_to_nodes_compressed) * per_body, double(wire.wire_table_to_nodes) * per_body,
                double(wire.wire_table_from_nodes) * per_body, wire.bad_messages, wire.recomputed_islands,
                wire.reassigned_islands, wire.dropped_nodes);
  std::printf("state hash   %s\n", hash);
  if (!o.out.empty()) std::printf("trajectory   %s\n", o.out.c_str());
  if (!o.stats.empty()) std::printf("statistics   %s\n", o.stats.c_str());
  if (!o.save_snapshot.empty()) std::printf("snapshot     %s\n", o.save_snapshot.c_str());
  return failed ? 1 : 0;
}

}  // namespace

int run_main(int argc, char** argv) {
  Options o;
  try {
    if (!parse_options(argc, argv, o)) {
      std::printf(kRunHelp, spu::integrator_names().c_str(), spu::solver_names().c_str(), ppe::kMaxWorkers);
      return 0;
    }
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cellphys run: %s\n(`cellphys run --help` lists the options)\n", e.message.c_str());
    return 2;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
#ifdef CELLPHYS_HAVE_MPI
  std::unique_ptr<ppe::MpiSession> session;  // declared first: outlives the runner and the world
#endif
  std::shared_ptr<ppe::IslandRunner> runner;
#ifdef CELLPHYS_HAVE_MPI
  if (o.mpi) {
    ppe::MpiOptions mo;
    mo.deadline_ms = o.mpi_deadline_ms;
    mo.corrupt_reply = o.mpi_corrupt;
    mo.silent_after = o.mpi_silent;
    try {
      session = std::make_unique<ppe::MpiSession>(nullptr, nullptr);
      if (session->rank() > 0) {
        ppe::run_compute_node(mo);  // until rank 0 is done
        return 0;
      }
      runner = std::make_shared<ppe::MpiRunner>(mo);  // its destructor stops the nodes, whatever happens
    } catch (const std::exception& e) {
      std::fprintf(stderr, "cellphys: %s\n", e.what());
      return 1;
    }
  }
#else
  if (o.mpi) {
    std::fprintf(stderr, "cellphys run: --mpi: this cellphys was built without MPI (install libopenmpi-dev)\n");
    return 2;
  }
#endif
  try {
    return run(o, runner);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cellphys run: %s\n", e.message.c_str());
    return 2;
  } catch (const scene::SceneError& e) {
    std::fprintf(stderr, "cellphys: %s\n", e.what());
    return 2;
  } catch (const SnapshotError& e) {
    std::fprintf(stderr, "cellphys: %s\n", e.message.c_str());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cellphys: %s\n", e.what());
    return 1;
  }
}

int scenes_main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::puts("usage: cellphys scenes\n\nLists the built-in scenes (name and description); run one with "
                "`cellphys run NAME`.");
      return 0;
    }
    std::fprintf(stderr, "cellphys scenes: unexpected argument '%s'\n", a.c_str());
    return 2;
  }
  const std::vector<BuiltinScene> all = builtin_scenes();
  if (all.empty()) {
    std::fprintf(stderr, "cellphys scenes: no built-in scenes found (set CELLPHYS_SCENES)\n");
    return 1;
  }
  size_t width = 0;
  for (const BuiltinScene& b : all) width = std::max(width, b.name.size());
  int rc = 0;
  for (const BuiltinScene& b : all) {
    try {
      const scene::SceneDesc d = scene::load_scene(b.path);
      std::printf("%-*s  %s%s\n", static_cast<int>(width), b.name.c_str(), d.description.c_str(),
                  b.name == kDefaultScene ? " (default)" : "");
    } catch (const scene::SceneError& e) {
      std::fprintf(stderr, "cellphys: %s\n", e.what());
      rc = 1;
    }
  }
  return rc;
}

}  // namespace cellphys::cli
