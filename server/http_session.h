// One HTTP connection: GET /metrics, GET / (the viewer, server/static_files.h), and the upgrade
// of /ws?world=NAME[&token=TOKEN] to a WebSocket client of that room (server/ws_session.h).
#pragma once
#include <boost/asio/ip/tcp.hpp>
#include <memory>

#include "server/server_context.h"

namespace cellphys::server {

/// Serves the connection until it closes or is upgraded.
void serve_http(boost::asio::ip::tcp::socket&& socket, const ServerContext& ctx);

}  // namespace cellphys::server
