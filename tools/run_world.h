// The world `cellphys run` steps: built from a scene (a file or a built-in name) or restored from
// a snapshot, with the command line's settings (--dt, --integrator, ...) applied.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "tools/run_options.h"

namespace cellphys::cli {

struct RunWorld {
  std::string arg, file, description;  // the SCENE (or snapshot) argument and the file it names
  std::unique_ptr<ppe::World> world;
  std::vector<ppe::BodyId> bodies;
  std::vector<std::string> ids;  // CSV body column, in `bodies` order
  long long forces = -1;         // unknown for a snapshot
  bool resumed = false;
};

// Throws UsageError (a bad scene name or setting), scene::SceneError (a bad scene file) or
// SnapshotError (a snapshot that cannot be resumed).
RunWorld load_run_world(const RunOptions& o);

}  // namespace cellphys::cli
