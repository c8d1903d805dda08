// `cellphys run`: load the world (tools/run_world.h), step it, and report: a summary on stdout,
// optionally a trajectory CSV, a statistics JSON and a snapshot of the world, all written
// atomically (tools/atomic_file.h) so a failed or interrupted run never leaves a partial file.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "runtime/ppe/island_runner.h"
#include "runtime/scene/scene.h"
#include "runtime/spu/simd.h"
#include "tools/atomic_file.h"
#include "tools/cli.h"
#include "tools/interrupt.h"
#include "tools/progress_bar.h"
#include "tools/run_options.h"
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

std::string scene_label(const std::string& arg, const std::string& file) {
  return arg == file ? file : arg + " (" + file + ")";
}

int run(const RunOptions& o, std::shared_ptr<ppe::IslandRunner> runner) {
  RunWorld loaded = load_run_world(o);
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
    write_trajectory_header(out.get());
    write_trajectory_rows(out.get(), world, loaded.bodies, 0, 0.0, ids);
  }
  if (!o.stats.empty()) stats_file.open(o.stats);

  const double ke0 = world.kinetic_energy();
  std::vector<double> step_ms;
  step_ms.reserve(static_cast<size_t>(std::min<long long>(steps, 10000000)));
  uint64_t iterations = 0, solves = 0, halvings = 0, failed = 0, decoupled = 0, contacts_max = 0;
  ppe::StepStats wire;  // transport and wire-table totals over the run
  size_t ls_peak = 0;
  ProgressBar progress(steps);
  const auto t0 = Clock::now();
  for (long long s = 1; s <= steps; ++s) {
    if (const int sig = interrupt_signal()) {
      progress.finish();
      std::fprintf(stderr, "cellphys: interrupted at step %lld of %lld; no trajectory or statistics written%s\n", s - 1,
                   steps, o.snapshot_every > 0 ? " (periodic snapshots stay)" : "");
      return 128 + sig;
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
      write_trajectory_rows(out.get(), world, loaded.bodies, static_cast<uint64_t>(s), double(s) * dt, ids);
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
    j["solver"] = scene::solver_name(settings.solver);
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
              spu::integrator_name(settings.integrator), scene::solver_name(settings.solver),
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
  RunOptions o;
  try {
    if (!parse_run_options(argc, argv, o)) {
      std::fputs(kRunHelp, stdout);
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
