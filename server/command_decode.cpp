#include <string>

#include "server/command.h"

namespace cellphys::server {

namespace {

bool fail(CommandError& err, protocol::ErrorCode code, std::string field, std::string reason) {
  err.code = code;
  err.field = std::move(field);
  err.reason = std::move(reason);
  return false;
}

}  // namespace

bool decode_client_message(const unsigned char* data, size_t size, Command& out, CommandError& err) {
  using protocol::ErrorCode;
  if (size < sizeof(protocol::Header))
    return fail(err, ErrorCode::malformed, "header",
                std::to_string(size) + " bytes is shorter than a message header (8 bytes)");
  protocol::Header h;
  std::memcpy(&h, data, sizeof h);
  if (h.length != size)
    return fail(err, ErrorCode::malformed, "header.length",
                "says " + std::to_string(h.length) + " bytes, the message has " + std::to_string(size));
  if (h.version != protocol::kVersion)
    return fail(err, ErrorCode::malformed, "header.version",
                "version " + std::to_string(h.version) + " is not this server's (" + std::to_string(protocol::kVersion) +
                    ")");
  const size_t want = protocol::client_message_size(h.type);
  if (want == 0)
    return fail(err, ErrorCode::malformed, "header.type", "type " + std::to_string(h.type) + " is not a client message");
  if (size != want)
    return fail(err, ErrorCode::malformed, "header.length",
                std::string(protocol::type_name(h.type)) + " is " + std::to_string(want) + " bytes, got " +
                    std::to_string(size));
  out = Command{};
  out.type = h.type;
  out.size = static_cast<uint32_t>(size);
  std::memcpy(out.bytes, data, size);
  if (out.changes_world()) std::memcpy(&out.seq, data + sizeof(protocol::Header), 4);
  return true;
}

}  // namespace cellphys::server
