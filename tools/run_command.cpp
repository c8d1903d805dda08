// `cellphys run`: load the world (tools/run_world.h), step it, and report (tools/run_report.h): a
// summary on stdout, optionally a trajectory CSV, an events CSV, a statistics JSON and a snapshot of the world,
// each written atomically (tools/atomic_file.h) so a failed or interrupted run leaves no partial
// file.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "runtime/ppe/island_runner.h"
#include "runtime/scene/scene.h"
#include "tools/atomic_file.h"
#include "tools/cli.h"
#include "tools/events_csv.h"
#include "tools/interrupt.h"
#include "tools/progress_bar.h"
#include "tools/run_options.h"
#include "tools/run_report.h"
#include "tools/run_totals.h"
#include "tools/run_world.h"
#include "tools/snapshot_file.h"
#include "tools/trajectory_csv.h"
#include "tools/usage_error.h"
#ifdef CELLPHYS_HAVE_MPI
#include "runtime/ppe/mpi_runner.h"
#endif

namespace cellphys::cli {

namespace {

using Clock = std::chrono::steady_clock;

constexpr double kDefaultDuration = 5.0;  // s of simulated time when neither --duration nor --steps

long long step_count(const RunOptions& o, double dt) {
  if (o.steps >= 0) return o.steps;
  const double duration = o.duration > 0 ? o.duration : kDefaultDuration;
  const double n = std::ceil(duration / dt - 1e-9);
  if (!(n <= 1e9)) throw UsageError{"--duration / dt is more than 1e9 steps"};  // before the cast
  return static_cast<long long>(n);
}

int run(const RunOptions& o, std::shared_ptr<ppe::IslandRunner> runner) {
  const RunWorld w = load_run_world(o);
  ppe::World& world = *w.world;
  if (runner) world.set_runner(runner);
  const double dt = world.settings().dt;
  RunOutcome r;
  r.steps = step_count(o, dt);
  r.runner = runner ? runner->name() : nullptr;
  r.totals = RunTotals(r.steps);

  AtomicFile out, stats_file, events_file;
  if (!o.out.empty()) {
    out.open(o.out);
    write_trajectory_header(out.get());
    write_trajectory_rows(out.get(), world, w.bodies, 0, 0.0, w.ids);
  }
  const EventsCsv events(w.bodies, w.ids);
  if (!o.events.empty()) {
    events_file.open(o.events);
    events.write_header(events_file.get());
  }
  if (!o.stats.empty()) stats_file.open(o.stats);
  if (!o.save_snapshot.empty()) AtomicFile().open(o.save_snapshot);  // an unwritable place fails now, not at the end

  r.kinetic_energy_initial = world.kinetic_energy();
  ProgressBar progress(r.steps);
  const auto t0 = Clock::now();
  for (long long s = 1; s <= r.steps; ++s) {
    if (const int sig = interrupt_signal()) {
      progress.finish();
      std::fprintf(stderr, "cellphys: interrupted at step %lld of %lld; no trajectory or statistics written%s\n", s - 1,
                   r.steps, o.snapshot_every > 0 ? " (periodic snapshots stay)" : "");
      return 128 + sig;
    }
    const auto a = Clock::now();
    const ppe::StepStats& st = world.step();
    r.totals.add(st, std::chrono::duration<double, std::milli>(Clock::now() - a).count());
    if (events_file.is_open()) events.write_step(events_file.get(), world, static_cast<uint64_t>(s), double(s) * dt);
    if (out.is_open() && s % o.every == 0)
      write_trajectory_rows(out.get(), world, w.bodies, static_cast<uint64_t>(s), double(s) * dt, w.ids);
    if (o.snapshot_every > 0 && s % o.snapshot_every == 0 && s < r.steps) save_snapshot(world, o.save_snapshot);
    progress.update(s);
  }
  r.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  progress.finish();
  r.kinetic_energy_final = world.kinetic_energy();

  if (stats_file.is_open()) {
    const std::string text = stats_json(o, w, r);
    std::fwrite(text.data(), 1, text.size(), stats_file.get());
  }
  // The files are complete; move them into place (a failure removes what is left), then the
  // snapshot, so a failed commit leaves no new snapshot either.
  if (out.is_open()) out.commit();
  if (events_file.is_open()) events_file.commit();
  if (stats_file.is_open()) stats_file.commit();
  if (!o.save_snapshot.empty()) save_snapshot(world, o.save_snapshot);
  print_summary(o, w, r);
  return r.totals.failed_islands ? 1 : 0;
}

}  // namespace

int run_main(int argc, char** argv) {
  RunOptions o;
  try {
    if (!parse_run_options(argc, argv, o)) {
      std::fputs(run_help().c_str(), stdout);
      return 0;
    }
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cellphys run: %s\n(`cellphys run --help` lists the options)\n", e.message.c_str());
    return 2;
  }
  catch_interrupts();
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
    mo.hang_after = o.mpi_hang;
    mo.kill_after = o.mpi_kill;
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

}  // namespace cellphys::cli
