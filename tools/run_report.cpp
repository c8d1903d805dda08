#include "tools/run_report.h"

#include <cstdio>

#include <nlohmann/json.hpp>

#include "runtime/scene/scene.h"
#include "runtime/base/simd.h"

namespace cellphys::cli {

namespace {

// The figures both reports derive from the world and the totals.
struct Derived {
  uint32_t static_bodies = 0, active = 0, sleeping = 0;
  double median_ms = 0, iterations_mean = 0;
  double per_body = 0;  // 1 / bodies shipped in islands, for the transport figures
  char hash[32] = {};
  const char* runner = "threads";
};

Derived derive(const RunWorld& w, const RunOutcome& r) {
  const ppe::World& world = *w.world;
  const RunTotals& t = r.totals;
  Derived d;
  for (ppe::BodyId id : w.bodies) d.static_bodies += world.is_static(id) ? 1 : 0;
  // Before any step, every dynamic body counts as active.
  d.active = r.steps > 0 ? static_cast<uint32_t>(t.active_bodies)
                         : static_cast<uint32_t>(w.bodies.size()) - d.static_bodies;
  d.sleeping = r.steps > 0 ? static_cast<uint32_t>(t.sleeping_bodies) : 0;
  d.median_ms = t.median_step_ms();
  d.iterations_mean = t.solves ? double(t.solver_iterations) / double(t.solves) : 0.0;
  d.per_body = t.island_bodies ? 1.0 / double(t.island_bodies) : 0.0;
  std::snprintf(d.hash, sizeof d.hash, "%016llx", static_cast<unsigned long long>(world.state_hash()));
  if (r.runner) d.runner = r.runner;
  return d;
}

std::string scene_label(const std::string& arg, const std::string& file) {
  return arg == file ? file : arg + " (" + file + ")";
}

}  // namespace

std::string stats_json(const RunOptions& o, const RunWorld& w, const RunOutcome& r) {
  const ppe::WorldSettings& settings = w.world->settings();
  const RunTotals& t = r.totals;
  const Derived d = derive(w, r);
  const double dt = settings.dt;
  nlohmann::ordered_json j;
  j["scene"] = w.arg;
  j["scene_file"] = w.file;
  j["integrator"] = spu::integrator_name(settings.integrator);
  j["solver"] = spu::solver_name(settings.solver);
  j["dt"] = dt;
  j["workers"] = settings.workers;
  j["simd_path"] = simd::kPathName;
  j["steps"] = r.steps;
  j["step_counter"] = w.world->last_stats().step;  // the world's, at the end: a resumed run counts on from its snapshot's
  j["sim_time_s"] = double(r.steps) * dt;
  j["wall_s"] = r.wall_s;
  j["ms_per_step_median"] = d.median_ms;
  j["ms_per_step_mean"] = r.steps ? r.wall_s * 1000.0 / double(r.steps) : 0.0;
  j["ms_per_step_max"] = t.max_step_ms();
  nlohmann::ordered_json stages;  // mean ms per step of each stage, in step order
  for (const ppe::StageTimeField& f : ppe::kStageTimeFields)
    stages[f.name] = r.steps ? t.stage_ms.*f.ms / double(r.steps) : 0.0;
  j["stage_ms_mean"] = stages;
  j["bodies"] = w.bodies.size();
  j["static_bodies"] = d.static_bodies;
  if (w.forces >= 0) j["forces"] = w.forces;
  else j["forces"] = nullptr;  // a snapshot's forces are not listed
  j["active_bodies"] = d.active;
  j["sleeping_bodies"] = d.sleeping;
  j["islands"] = t.islands;
  j["contacts"] = t.contacts;
  j["contacts_max"] = t.contacts_max;
  j["solver_iterations_mean"] = d.iterations_mean;
  j["solver_iterations_total"] = t.solver_iterations;
  j["solves"] = t.solves;
  j["step_halvings"] = t.step_halvings;
  j["failed_islands"] = t.failed_islands;
  j["local_store_peak_bytes"] = t.local_store_peak_bytes;
  j["decoupled_islands"] = t.decoupled_islands;
  j["pushed_bodies"] = t.pushed_bodies;
  j["kinetic_energy_initial"] = r.kinetic_energy_initial;
  j["kinetic_energy_final"] = r.kinetic_energy_final;
  j["state_hash"] = d.hash;
  j["runner"] = d.runner;
  if (w.resumed) j["resumed_from"] = o.resume;
  if (!o.save_snapshot.empty()) j["snapshot"] = o.save_snapshot;
  nlohmann::ordered_json tr;
  tr["island_bodies"] = t.island_bodies;  // body records shipped, summed over steps
  tr["bytes_to_nodes"] = t.bytes_to_nodes;
  tr["bytes_from_nodes"] = t.bytes_from_nodes;
  tr["bytes_to_nodes_per_body"] = double(t.bytes_to_nodes) * d.per_body;
  tr["bytes_from_nodes_per_body"] = double(t.bytes_from_nodes) * d.per_body;
  tr["messages"] = t.messages;
  tr["table_to_nodes_per_body"] = double(t.wire_table_to_nodes) * d.per_body;
  tr["table_to_nodes_compressed_per_body"] = double(t.wire_table_to_nodes_compressed) * d.per_body;
  tr["table_from_nodes_per_body"] = double(t.wire_table_from_nodes) * d.per_body;
  tr["shared_per_body"] = double(t.island_bytes_shared) * d.per_body;
  tr["image_bytes_per_body"] = double(t.image_bytes) * d.per_body;
  tr["result_bytes_per_body"] = double(t.result_bytes) * d.per_body;
  tr["bad_messages"] = t.bad_messages;
  tr["recomputed_islands"] = t.recomputed_islands;
  tr["reassigned_islands"] = t.reassigned_islands;
  tr["dropped_nodes"] = t.dropped_nodes;
  j["transport"] = tr;
  return j.dump(2) + "\n";
}

void print_summary(const RunOptions& o, const RunWorld& w, const RunOutcome& r) {
  const ppe::WorldSettings& settings = w.world->settings();
  const RunTotals& t = r.totals;
  const Derived d = derive(w, r);
  const double dt = settings.dt;
  const auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  if (w.resumed)
    std::printf("resumed      %s\n", w.file.c_str());
  else
    std::printf("scene        %s\n", scene_label(w.arg, w.file).c_str());
  if (!w.description.empty()) std::printf("description  %s\n", w.description.c_str());
  if (w.forces >= 0)
    std::printf("bodies       %zu (%u static), %lld forces\n", w.bodies.size(), d.static_bodies, w.forces);
  else
    std::printf("bodies       %zu (%u static)\n", w.bodies.size(), d.static_bodies);
  std::printf("settings     dt %.6g s, %s, %s, tolerance %g, %d worker%s, SIMD %s\n", dt,
              spu::integrator_name(settings.integrator), spu::solver_name(settings.solver),
              double(settings.tolerance), settings.workers, settings.workers == 1 ? "" : "s", simd::kPathName);
  std::printf("run          %lld steps, %.4g s simulated in %.3f s wall, median %.3f ms per step\n", r.steps,
              double(r.steps) * dt, r.wall_s, d.median_ms);
  std::printf("at the end   %u active, %u sleeping, %llu islands, %llu contacts\n", d.active, d.sleeping,
              u(t.islands), u(t.contacts));
  std::printf("solver       %.2f iterations per solve, %llu step halvings, %llu failed islands\n", d.iterations_mean,
              u(t.step_halvings), u(t.failed_islands));
  std::printf("local store  peak %llu bytes, %llu decoupled islands\n", u(t.local_store_peak_bytes),
              u(t.decoupled_islands));
  std::printf("energy       kinetic %.6g J at the start, %.6g J at the end\n", r.kinetic_energy_initial,
              r.kinetic_energy_final);
  if (r.runner)
    std::printf("transport    %s: %.1f bytes per body out, %.1f back (tables: %.1f compressed, %.1f with geometry, "
                "%.1f back); %llu bad messages, %llu islands recomputed, %llu reassigned, %llu nodes dropped\n",
                d.runner, double(t.bytes_to_nodes) * d.per_body, double(t.bytes_from_nodes) * d.per_body,
                double(t.wire_table_to_nodes_compressed) * d.per_body, double(t.wire_table_to_nodes) * d.per_body,
                double(t.wire_table_from_nodes) * d.per_body, u(t.bad_messages), u(t.recomputed_islands),
                u(t.reassigned_islands), u(t.dropped_nodes));
  std::printf("state hash   %s\n", d.hash);
  if (!o.out.empty()) std::printf("trajectory   %s\n", o.out.c_str());
  if (!o.stats.empty()) std::printf("statistics   %s\n", o.stats.c_str());
  if (!o.save_snapshot.empty()) std::printf("snapshot     %s\n", o.save_snapshot.c_str());
}

}  // namespace cellphys::cli
