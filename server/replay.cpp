#include "server/replay.h"

#include "server/world_commands.h"

namespace cellphys::server {

ReplayResult replay(const Recording& r) {
  ReplayResult out;
  WorldCommands cmds(r.snapshot);
  auto step_to = [&](uint64_t step) {
    while (cmds.world().last_stats().step < step) {
      cmds.world().step();
      ++out.steps;
    }
  };
  for (const RecordEntry& e : r.entries) {
    step_to(e.step);
    if (e.type == RecordType::command) {
      Applied a;
      if (auto err = cmds.apply(e.command, a)) {
        out.refused = "the command at step " + std::to_string(e.step) + " (" + protocol::type_name(e.command.type) +
                      ") was refused: " + err->field + ": " + err->reason;
        out.matched = false;
        out.mismatch_step = e.step;
        break;
      }
      ++out.commands;
      continue;
    }
    const uint64_t h = cmds.world().state_hash();
    ++out.hashes_checked;
    if (h != e.hash) {
      out.matched = false;
      out.mismatch_step = e.step;
      out.recorded_hash = e.hash;
      out.replayed_hash = h;
      break;
    }
  }
  out.final_step = cmds.world().last_stats().step;
  out.final_hash = cmds.world().state_hash();
  return out;
}

}  // namespace cellphys::server
