// Recordings of a served world (`cellphys serve --record`, `cellphys replay`, the viewer): the
// world's starting snapshot, then every applied command with the step it was applied at, the
// state hash after every step and (version 2, unless `--record-frames off`) the state messages
// the server sent: the bytes a client watching every body at full precision got
// (server/watcher_stream.h), so a recording can be drawn without simulating it. Records are
// appended with a length and checksum each and flushed every tick, so the file of a server that
// was killed reads up to its last whole record; a clean stop appends an end record.
//
// File: "CELLREC1" | u32 version (1 or 2) | u32 flags (version 2: 1 = frames recorded, 2 = and
// debug messages; 0 in version 1) | records. Record: u32 type | u32 payload bytes | u32 checksum (spu::checksum of the
// record with this field zero, then of the payload) | u32 0 | payload:
//   world    u32 name bytes | name | World::snapshot() bytes
//   command  u64 step | the command's protocol bytes (server/protocol.h)
//   hash     u64 step | u64 World::state_hash() after that step
//   end      u64 step | u64 state hash
//   frame    u64 step | one server message's protocol bytes: a join or a tick, each followed by
//            the stages message of the same frame (version 2) and, with flag 2
//            (`--record-debug on`), its debug message
// A frame follows the command and hash records of its tick (docs/server.md, "Recording").
#pragma once
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/command.h"

namespace cellphys::server {

class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class RecordType : uint32_t { world = 1, command = 2, hash = 3, end = 4, frame = 5 };

inline constexpr uint32_t kRecordingVersion = 2;   // what this cellphys writes; it reads 1 and 2
inline constexpr uint32_t kRecordingFrames = 1u;   // header flag: frame records follow each published state
inline constexpr uint32_t kRecordingDebug = 2u;    // header flag: each frame's debug message is recorded too

class RecordingWriter {
 public:
  /// Creates (or truncates) the file; throws RecordingError naming it. `frames`: the state
  /// messages will be recorded; `debug`: and each frame's debug message (the header says so).
  explicit RecordingWriter(const std::string& path, bool frames = true, bool debug = false);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  void world(const std::string& name, const std::vector<unsigned char>& snapshot);
  void command(uint64_t step, const Command& c);
  void hash(uint64_t step, uint64_t state_hash);
  /// A state message as sent, for the frame at `step`.
  void frame(uint64_t step, const std::vector<unsigned char>& message);
  bool frames() const { return frames_; }
  bool debug() const { return debug_; }
  /// Pushes what was written to the file (every tick).
  void flush();
  /// Appends the end record and closes; throws RecordingError if a write failed at any point.
  void close(uint64_t step, uint64_t state_hash);
  const std::string& path() const { return path_; }

 private:
  void record(RecordType type, const unsigned char* a, size_t na, const unsigned char* b = nullptr, size_t nb = 0);
  std::string path_;
  FILE* f_ = nullptr;
  bool failed_ = false;
  bool frames_ = true;
  bool debug_ = false;
};

struct RecordEntry {
  RecordType type = RecordType::hash;
  uint64_t step = 0;
  uint64_t hash = 0;  // hash, end
  Command command;    // command
  std::vector<unsigned char> message;  // frame: the server message's bytes
};

struct Recording {
  uint32_t version = kRecordingVersion;
  bool frames = false;  // the state messages were recorded (version 2 and its header's flag)
  bool debug = false;   // and each frame's debug message
  std::string world;
  std::vector<unsigned char> snapshot;
  std::vector<RecordEntry> entries;  // after the world record, in file order (the end record last, if any)
  bool ended = false;
  /// Empty, or why reading stopped before the end of the file (a record cut short or damaged:
  /// the server was killed while writing it).
  std::string damage;
};

/// Reads a recording; throws RecordingError naming the file when it is missing, not a
/// recording, of a version this cellphys does not read, or has no sound world record.
Recording read_recording(const std::string& path);

}  // namespace cellphys::server
