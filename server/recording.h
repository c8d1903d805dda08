// Recordings of a served world (`cellphys serve --record`, `cellphys replay`): the world's
// starting snapshot, then every applied command with the step it was applied at, and the state
// hash after every step. Records are appended with a length and checksum each and flushed every
// tick, so the file of a server that was killed reads up to its last whole record; a clean stop
// appends an end record.
//
// File: "CELLREC1" | u32 version | u32 0 | records. Record: u32 type | u32 payload bytes |
// u32 checksum (spu::checksum of the record with this field zero, then of the payload) | u32 0 |
// payload:
//   world    u32 name bytes | name | World::snapshot() bytes
//   command  u64 step | the command's protocol bytes (server/protocol.h)
//   hash     u64 step | u64 World::state_hash() after that step
//   end      u64 step | u64 state hash
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

enum class RecordType : uint32_t { world = 1, command = 2, hash = 3, end = 4 };

class RecordingWriter {
 public:
  /// Creates (or truncates) the file; throws RecordingError naming it.
  explicit RecordingWriter(const std::string& path);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  void world(const std::string& name, const std::vector<unsigned char>& snapshot);
  void command(uint64_t step, const Command& c);
  void hash(uint64_t step, uint64_t state_hash);
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
};

struct RecordEntry {
  RecordType type = RecordType::hash;
  uint64_t step = 0;
  uint64_t hash = 0;  // hash, end
  Command command;    // command
};

struct Recording {
  std::string world;
  std::vector<unsigned char> snapshot;
  std::vector<RecordEntry> entries;  // after the world record, in file order (the end record last, if any)
  bool ended = false;
  /// Empty, or why reading stopped before the end of the file (a record cut short or damaged:
  /// the server was killed while writing it).
  std::string damage;
};

/// Reads a recording; throws RecordingError naming the file when it is missing, not a
/// recording, or has no sound world record.
Recording read_recording(const std::string& path);

}  // namespace cellphys::server
