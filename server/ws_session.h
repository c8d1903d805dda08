// One WebSocket client of a room (/ws?world=NAME[&token=TOKEN][&revision=N]). It reads the client's messages
// (interest, commands: checked for the token and rate limited here, applied by the room) and
// writes, one message at a time, the room's answers (never dropped) and its newest state: a
// frame that arrives while a write is in flight replaces the one waiting, and the next tick
// tells the client how many it skipped. A client whose write has not completed within the
// deadline (it stopped reading) is dropped, so no client holds up the room or other clients. A
// client that reads an older protocol revision than the world's join needs gets an error saying
// so, and is closed, instead of a join it would misread.
#pragma once
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <deque>
#include <memory>
#include <vector>

#include "server/rate_limiter.h"
#include "server/server_context.h"
#include "server/state_encoder.h"

namespace cellphys::server {

class WsSession : public ClientSink, public std::enable_shared_from_this<WsSession> {
 public:
  /// `revision`: the protocol revision the client said it reads (0: it said none).
  WsSession(boost::asio::ip::tcp::socket&& socket, std::shared_ptr<Room> room, bool can_command, uint32_t revision,
            const ServerContext& ctx);
  ~WsSession() override;

  /// Completes the WebSocket handshake of an upgrade request, then serves the client.
  void run(boost::beast::http::request<boost::beast::http::string_body> request);

  void on_frame(std::shared_ptr<const Frame> frame) override;
  void on_message(std::shared_ptr<const std::vector<unsigned char>> message) override;

 private:
  void on_accept(boost::beast::error_code ec);
  void refuse_revision();
  void do_read();
  void on_read(boost::beast::error_code ec, size_t bytes);
  void handle(const unsigned char* data, size_t size);
  void refuse(uint32_t seq, uint16_t type, protocol::ErrorCode code, std::string field, std::string reason);
  void maybe_write();
  void on_write(boost::beast::error_code ec, size_t bytes);
  std::shared_ptr<const std::vector<unsigned char>> encode(const Frame& f);
  void watch_deadline();
  void close(boost::beast::websocket::close_code code);
  void drop();  // a client that does not read: off the room, counted

  boost::beast::websocket::stream<boost::beast::tcp_stream> ws_;
  boost::beast::flat_buffer read_buffer_;
  boost::asio::steady_timer deadline_timer_;
  std::shared_ptr<Room> room_;
  const ServerContext& ctx_;
  const bool can_command_;
  const uint32_t revision_;
  RateLimiter limiter_;
  uint64_t refused_in_a_row_ = 0;

  // What the client holds: the frame its last message was encoded from and the ids it has.
  Interest interest_;
  bool joined_ = false, synced_full_ = false;
  uint32_t epoch_ = 0;
  uint64_t last_seq_ = 0;
  std::vector<uint32_t> known_;
  uint32_t skipped_ = 0;

  std::deque<std::shared_ptr<const std::vector<unsigned char>>> control_;
  std::shared_ptr<const Frame> pending_;
  std::shared_ptr<const std::vector<unsigned char>> writing_;
  // The stages and debug messages of the frame just written, written right after it, in order.
  std::deque<std::shared_ptr<const std::vector<unsigned char>>> follow_;
  std::chrono::steady_clock::time_point write_started_;
  bool open_ = false, closed_ = false;
};

}  // namespace cellphys::server
