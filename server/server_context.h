// What every connection of a server shares: its rooms, its token and its policies.
#pragma once
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "server/room.h"

namespace cellphys::server {

struct ServerOptions {
  std::string host = "127.0.0.1";
  unsigned short port = 8080;  // 0: any free port
  std::string token;           // empty: a random one
  std::string viewer_dir;      // served at /, if it exists
  int io_threads = 1;
  double command_rate = 60;    // commands a second per connection, on average
  double command_burst = 120;  // and in a burst
  double client_deadline_s = 5;  // a client whose write has not completed for this long is dropped
  int client_send_buffer = 256 * 1024;  // bytes the system may hold for one client (its queue's bound)
};

struct ServerContext {
  ServerOptions options;
  std::vector<std::shared_ptr<Room>> rooms;
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();

  /// The room of that name; with an empty name, the first.
  std::shared_ptr<Room> room(const std::string& name) const {
    if (name.empty()) return rooms.empty() ? nullptr : rooms.front();
    for (const auto& r : rooms)
      if (r->name() == name) return r;
    return nullptr;
  }
};

}  // namespace cellphys::server
