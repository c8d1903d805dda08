// The game server: rooms (each its own thread) behind one HTTP/WebSocket listener
// (Boost.Beast on Boost.Asio, on options.io_threads threads). docs/server.md.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "server/server_context.h"

namespace cellphys::server {

class Server {
 public:
  /// Binds the listener (throws std::runtime_error naming the address when it cannot); a
  /// missing token is replaced by a random one.
  Server(ServerOptions options, std::vector<std::shared_ptr<Room>> rooms);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  unsigned short port() const;
  const std::string& host() const;
  const std::string& token() const;
  /// Starts the rooms and serves until SIGINT or SIGTERM (or stop()), then stops the rooms
  /// (closing their recordings).
  void run();
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// 32 hex digits from the system's random source.
std::string random_token();

}  // namespace cellphys::server
