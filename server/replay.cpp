#include "server/replay.h"

#include <cstring>
#include <memory>

#include "server/debug_encoder.h"
#include "server/frame_builder.h"
#include "server/message_decode.h"
#include "server/play_state.h"
#include "server/stages_encoder.h"
#include "server/state_encoder.h"
#include "server/watcher_stream.h"
#include "server/world_commands.h"

namespace cellphys::server {

namespace {

template <class T>
T field_at(const std::vector<unsigned char>& m, size_t at) {
  T v{};
  if (m.size() >= at + sizeof v) std::memcpy(&v, m.data() + at, sizeof v);
  return v;
}

uint16_t type_of(const std::vector<unsigned char>& m) { return field_at<uint16_t>(m, offsetof(protocol::Header, type)); }

/// Where two state messages first differ, in words: the message, the byte, and the part of its
/// layout that byte is in (a fixed field, or which body record).
std::string describe_difference(const std::vector<unsigned char>& recorded, const std::vector<unsigned char>& replayed) {
  const uint16_t type = type_of(recorded);
  std::string what = std::string(protocol::type_name(type)) + " of " + std::to_string(recorded.size()) + " bytes";
  if (replayed.empty()) return what + " recorded, none made again (no frame before it)";
  if (type_of(replayed) != type) return what + " recorded, a " + protocol::type_name(type_of(replayed)) + " replayed";
  size_t at = 0;
  while (at < recorded.size() && at < replayed.size() && recorded[at] == replayed[at]) ++at;
  std::string where = "byte " + std::to_string(at);
  if (type == static_cast<uint16_t>(protocol::Type::tick) && at >= sizeof(protocol::Tick)) {
    const auto ne = field_at<uint32_t>(recorded, offsetof(protocol::Tick, num_entered));
    const auto nm = field_at<uint32_t>(recorded, offsetof(protocol::Tick, num_moved));
    size_t k = at - sizeof(protocol::Tick);
    const char* part = "gone";
    size_t record = 0, size = 4;
    if (k < ne * sizeof(protocol::BodyFull)) {
      part = "entered", size = sizeof(protocol::BodyFull);
    } else {
      k -= ne * sizeof(protocol::BodyFull);
      if (k < nm * sizeof(protocol::BodyMoved))
        part = "moved", size = sizeof(protocol::BodyMoved);
      else
        k -= nm * sizeof(protocol::BodyMoved);
    }
    record = k / size;
    const size_t start = at - k % size;
    where += " (" + std::string(part) + " record " + std::to_string(record) + ", body " +
             std::to_string(field_at<uint32_t>(recorded, start)) + ")";
  } else if (type == static_cast<uint16_t>(protocol::Type::tick)) {
    where += " (the tick's fixed part)";
  }
  if (recorded.size() != replayed.size())
    where += "; replayed " + std::to_string(replayed.size()) + " bytes";
  return what + ", " + where;
}

/// The stage times of a recorded stages message, by the names this build gives its stages
/// (a stage it does not name stays 0: the message made again then differs, in its names).
ppe::StageTimes recorded_times(const std::vector<unsigned char>& m) {
  ppe::StageTimes t;
  StagesMessage s;
  if (!decode_stages(m.data(), m.size(), s).empty()) return t;
  for (const auto& [name, ms] : s.stages)
    for (const ppe::StageTimeField& f : ppe::kStageTimeFields)
      if (name == f.name) t.*(f.ms) = ms;
  return t;
}

}  // namespace

ReplayResult replay(const Recording& r, const std::function<void(const ppe::World&)>& on_step) {
  ReplayResult out;
  WorldCommands cmds(r.snapshot);
  PlayState play;
  WatcherStream stream;
  std::shared_ptr<const Frame> prev;
  uint64_t seq = 0;
  float tick_hz = 0;
  const auto shapes = std::make_shared<const std::vector<unsigned char>>(encode_shapes(cmds.world().shapes()));
  if (on_step) on_step(cmds.world());
  auto step_to = [&](uint64_t step) {
    while (cmds.world().last_stats().step < step) {
      cmds.world().step();
      play.stepped();
      ++out.steps;
      if (on_step) on_step(cmds.world());
    }
  };
  // A recorded message against the one made again; where they first differ when they do.
  auto same = [&](const RecordEntry& e, const std::vector<unsigned char>& mine) {
    if (mine == e.message) return true;
    out.matched = false;
    out.mismatch_step = e.step;
    out.frame_difference = describe_difference(e.message, mine);
    return false;
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
      play.applied(e.command.type);
      ++out.commands;
      continue;
    }
    if (e.type == RecordType::frame && type_of(e.message) == static_cast<uint16_t>(protocol::Type::stages)) {
      // The stages of the frame just made again, at the times the live server measured.
      ++out.stages_checked;
      const std::vector<unsigned char> mine =
          prev ? encode_stages(prev->step, prev->epoch, recorded_times(e.message)) : std::vector<unsigned char>{};
      if (!same(e, mine)) break;
      continue;
    }
    if (e.type == RecordType::frame && type_of(e.message) == static_cast<uint16_t>(protocol::Type::debug)) {
      // What the solver did in the step just made again: the same bytes.
      ++out.debug_checked;
      const std::vector<unsigned char> mine = encode_debug(cmds.world(), play.epoch);
      if (!same(e, mine)) break;
      continue;
    }
    if (e.type == RecordType::frame) {
      // The wall times are the live server's own: taken from the recording, not compared.
      const bool is_join = type_of(e.message) == static_cast<uint16_t>(protocol::Type::join);
      if (is_join) tick_hz = field_at<float>(e.message, offsetof(protocol::Join, tick_hz));
      FrameContext at;
      at.world = r.world;
      at.seq = ++seq;
      at.epoch = play.epoch;
      at.paused = play.paused;
      at.tick_hz = tick_hz;
      at.step_ms = is_join ? 0.0 : field_at<float>(e.message, offsetof(protocol::Tick, stats));
      at.shapes = shapes;
      const std::shared_ptr<const Frame> f = build_frame(cmds.world(), at, prev.get());
      prev = f;
      const auto made = stream.next(*f);
      ++out.frames_checked;
      // A recording made by an older revision: its join announces that revision. The world's
      // join is the same bytes if that revision could read this world's shapes (revision 4 changed
      // only what follows meshes, height fields and compounds), so it is compared as that one.
      std::vector<unsigned char> as_recorded;
      const std::vector<unsigned char>* mine = made.get();
      if (is_join) {
        const size_t at_rev = offsetof(protocol::Join, revision);
        const uint32_t rec = field_at<uint32_t>(e.message, at_rev), ours = field_at<uint32_t>(*made, at_rev);
        if (rec != ours && rec >= revision_needed(cmds.world().shapes()).revision && made->size() >= at_rev + 4) {
          as_recorded = *made;
          std::memcpy(as_recorded.data() + at_rev, &rec, 4);
          mine = &as_recorded;
        }
      }
      if (!same(e, *mine)) break;
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
