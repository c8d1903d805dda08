// A client message as the server reads it: framed and checked against protocol.h (length,
// type, version) before anything looks at its fields. Fields are checked against the world
// when the command is applied (server/world_commands.h).
#pragma once
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "server/protocol.h"

namespace cellphys::server {

/// Why a message or command was refused: the field it names ("spawn.orientation", "header.length")
/// and the reason, with the protocol's error code.
struct CommandError {
  protocol::ErrorCode code = protocol::ErrorCode::invalid;
  std::string field, reason;
};

/// One framed client message: its type, sequence number and bytes (at most the largest layout).
struct Command {
  static constexpr size_t kMaxBytes = sizeof(protocol::Spawn);
  uint16_t type = 0;
  uint32_t seq = 0;  // 0 for subscribe, which has none
  uint32_t size = 0;
  unsigned char bytes[kMaxBytes] = {};

  /// The message as its layout (T must be the layout of `type`).
  template <class T>
  T as() const {
    static_assert(sizeof(T) <= kMaxBytes);
    T t;
    std::memcpy(&t, bytes, sizeof t);
    return t;
  }
  /// True for the messages that change a world (everything but subscribe).
  bool changes_world() const { return type != static_cast<uint16_t>(protocol::Type::subscribe); }
};

/// Frames a client message. Returns false with `err` naming what is wrong (the header's length,
/// type or version; a size that is not the type's).
bool decode_client_message(const unsigned char* data, size_t size, Command& out, CommandError& err);

/// The bytes of a command message (header filled in): for clients, tests and the recorder.
template <class T>
Command make_command(protocol::Type type, T message) {
  message.header.length = sizeof(T);
  message.header.type = static_cast<uint16_t>(type);
  message.header.version = protocol::kVersion;
  Command c;
  c.type = message.header.type;
  c.size = sizeof(T);
  std::memcpy(c.bytes, &message, sizeof(T));
  if constexpr (sizeof(T) >= sizeof(protocol::CommandHead)) {
    if (type != protocol::Type::subscribe) std::memcpy(&c.seq, c.bytes + sizeof(protocol::Header), 4);
  }
  return c;
}

}  // namespace cellphys::server
