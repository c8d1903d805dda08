// A protocol client over WsClient for the server's tests: keeps a mirror of the bodies the
// server has sent (join, then each tick's entered, moved and gone), and the answers to its
// commands by sequence number.
#pragma once
#include <chrono>
#include <cstring>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/command.h"
#include "server/message_decode.h"
#include "tests/support/ws_client.h"

namespace cellphys::test {

class ServerClient {
 public:
  ServerClient(unsigned short port, const std::string& world, const std::string& token = "", int rcvbuf = 0)
      : ws_(port, "/ws?world=" + world + (token.empty() ? "" : "&token=" + token), rcvbuf) {}

  WsClient& ws() { return ws_; }

  /// Receives and takes in one message; false on a timeout or a closed connection.
  bool pump(std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    auto m = ws_.receive(timeout);
    if (!m) return false;
    take(*m);
    return true;
  }

  /// Pumps until `done()` holds; false if it does not within `timeout`.
  bool until(const std::function<bool()>& done, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!done()) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      if (left.count() <= 0 || !pump(left)) return done();
    }
    return true;
  }

  /// Sends a command (its header and sequence number filled in); returns the sequence number.
  template <class T>
  uint32_t command(server::protocol::Type type, T message) {
    const uint32_t seq = next_seq_++;
    if constexpr (sizeof(T) >= sizeof(server::protocol::CommandHead)) std::memcpy(reinterpret_cast<unsigned char*>(&message) + 8, &seq, 4);
    const server::Command c = server::make_command(type, message);
    ws_.send(c.bytes, c.size);
    return seq;
  }
  uint32_t control(server::protocol::Type type) { return command(type, server::protocol::Control{}); }
  void subscribe(const server::protocol::Subscribe& s) {
    const server::Command c = server::make_command(server::protocol::Type::subscribe, s);
    ws_.send(c.bytes, c.size);
  }

  /// Waits for the answer to `seq`: true for an ack, false for an error (in errors[seq]).
  bool answer(uint32_t seq) {
    if (!until([&] { return acks.count(seq) || errors.count(seq); }))
      throw std::runtime_error("no answer to command " + std::to_string(seq));
    return acks.count(seq) > 0;
  }

  // What was received.
  int joins = 0;
  server::JoinMessage join;
  std::map<uint32_t, server::protocol::BodyFull> bodies;  // the mirror, by id
  std::vector<server::TickMessage> ticks;                 // every tick since the last clear
  std::map<uint32_t, server::protocol::Ack> acks;
  std::map<uint32_t, server::ErrorMessage> errors;       // by seq (seq 0: messages that were not read)
  std::vector<server::StatusMessage> statuses;
  std::vector<server::StagesMessage> stages;  // every stages message since the last clear
  std::vector<uint64_t> stages_after;         // for each, the step of the state message it followed
  std::vector<server::DebugMessage> debugs;   // every debug message since the last clear
  uint64_t step = 0;
  std::string last_problem;  // a message that did not decode, or a redundant resend

 private:
  void take(const std::vector<unsigned char>& m) {
    namespace p = server::protocol;
    std::string e;
    switch (static_cast<p::Type>(server::message_type(m.data(), m.size()))) {
      case p::Type::join:
        e = server::decode_join(m.data(), m.size(), join);
        if (e.empty()) {
          ++joins;
          bodies.clear();
          for (const auto& b : join.bodies) bodies[b.id] = b;
          step = join.head.step;
        }
        break;
      case p::Type::tick: {
        server::TickMessage t;
        e = server::decode_tick(m.data(), m.size(), t);
        if (!e.empty()) break;
        for (const auto& b : t.entered) bodies[b.id] = b;
        for (const auto& [id, s] : t.moved) {
          auto it = bodies.find(id);
          if (it == bodies.end()) {
            last_problem = "moved body " + std::to_string(id) + " was never sent";
            continue;
          }
          server::protocol::BodyFull& b = it->second;
          if (!(t.head.flags & p::kTickQuantised) && std::memcmp(b.position, s.position, 12) == 0 &&
              std::memcmp(b.orientation, s.orientation, 16) == 0 && std::memcmp(b.velocity, s.velocity, 12) == 0 &&
              std::memcmp(b.angular_velocity, s.angular_velocity, 12) == 0)
            last_problem = "body " + std::to_string(id) + " resent unchanged";
          ppe::copy_state(s, b);
        }
        for (uint32_t id : t.gone) bodies.erase(id);
        step = t.head.step;
        ticks.push_back(std::move(t));
        break;
      }
      case p::Type::ack: {
        p::Ack a;
        e = server::decode_ack(m.data(), m.size(), a);
        if (e.empty()) acks[a.seq] = a;
        break;
      }
      case p::Type::error: {
        server::ErrorMessage x;
        e = server::decode_error(m.data(), m.size(), x);
        if (e.empty()) errors[x.head.seq] = x;
        break;
      }
      case p::Type::status: {
        server::StatusMessage s;
        e = server::decode_status(m.data(), m.size(), s);
        if (e.empty()) statuses.push_back(s);
        break;
      }
      case p::Type::stages: {
        server::StagesMessage s;
        e = server::decode_stages(m.data(), m.size(), s);
        if (e.empty()) {
          stages_after.push_back(step);
          stages.push_back(std::move(s));
        }
        break;
      }
      case p::Type::debug: {
        server::DebugMessage d;
        e = server::decode_debug(m.data(), m.size(), d);
        if (e.empty()) debugs.push_back(std::move(d));
        break;
      }
      default: e = "unknown message type";
    }
    if (!e.empty()) last_problem = e;
  }

  WsClient ws_;
  uint32_t next_seq_ = 1;
};

}  // namespace cellphys::test
