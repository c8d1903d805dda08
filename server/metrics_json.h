// GET /metrics: every room's figures (server/room.h RoomMetrics) as JSON (docs/server.md).
#pragma once
#include <string>

#include "server/server_context.h"

namespace cellphys::server {

std::string metrics_json(const ServerContext& ctx);

}  // namespace cellphys::server
