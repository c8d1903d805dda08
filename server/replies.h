// The server's answers that are not state: ack, error and status messages (server/protocol.h).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "server/command.h"

namespace cellphys::server {

using Message = std::shared_ptr<const std::vector<unsigned char>>;

Message encode_ack(const Command& c, uint64_t step, uint32_t result);
Message encode_error(uint32_t seq, uint16_t command_type, const CommandError& e);
Message encode_status(protocol::WorldState state, uint64_t step, const std::string& text);

}  // namespace cellphys::server
