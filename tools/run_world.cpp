#include "tools/run_world.h"

#include <cmath>
#include <cstdio>

#include "runtime/scene/scene.h"
#include "tools/builtin_scenes.h"
#include "tools/snapshot_file.h"
#include "tools/trajectory_csv.h"
#include "tools/usage_error.h"

namespace cellphys::cli {

namespace {

// Applies the command line's overrides to settings (a scene's or a snapshot's).
void apply_overrides(const RunOptions& o, ppe::WorldSettings& s) {
  if (o.dt > 0) s.dt = static_cast<float>(o.dt);
  if (!o.integrator.empty() && !spu::parse_integrator(o.integrator, &s.integrator))
    throw UsageError{"unknown integrator '" + o.integrator + "' (known: " + spu::integrator_names() + ")"};
  if (!o.solver.empty() && !spu::parse_solver(o.solver, &s.solver))
    throw UsageError{"unknown solver '" + o.solver + "' (known: " + spu::solver_names() + ")"};
  if (o.tolerance > 0) s.tolerance = static_cast<float>(o.tolerance);
  if (o.workers > 0) s.workers = o.workers;
  if (!(s.dt > 0.0f) || !std::isfinite(s.dt)) throw UsageError{"--dt is too small or too large"};
}

RunWorld restore(const RunOptions& o) {
  RunWorld l;
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

RunWorld build(const RunOptions& o) {
  RunWorld l;
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

}  // namespace

RunWorld load_run_world(const RunOptions& o) { return o.resume.empty() ? build(o) : restore(o); }

}  // namespace cellphys::cli
