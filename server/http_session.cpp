#include "server/http_session.h"

#include <boost/asio/dispatch.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <map>
#include <string>

#include "server/metrics_json.h"
#include "server/static_files.h"
#include "server/ws_session.h"

namespace cellphys::server {

namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;

int hex(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percent_decoded(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hex(s[i + 1]) >= 0 && hex(s[i + 2]) >= 0) {
      out += static_cast<char>(hex(s[i + 1]) * 16 + hex(s[i + 2]));
      i += 2;
    } else {
      out += s[i] == '+' ? ' ' : s[i];
    }
  }
  return out;
}

std::map<std::string, std::string> query_of(const std::string& q) {
  std::map<std::string, std::string> out;
  size_t at = 0;
  while (at < q.size()) {
    const size_t end = std::min(q.find('&', at), q.size());
    const std::string kv = q.substr(at, end - at);
    const size_t eq = kv.find('=');
    out[percent_decoded(kv.substr(0, eq))] = eq == std::string::npos ? "" : percent_decoded(kv.substr(eq + 1));
    at = end + 1;
  }
  return out;
}

// Compares without stopping at the first difference, so the time says nothing of the token.
bool same_token(const std::string& a, const std::string& b) {
  unsigned char d = a.size() == b.size() ? 0 : 1;
  for (size_t i = 0; i < a.size(); ++i) d |= static_cast<unsigned char>(a[i] ^ b[i % (b.empty() ? 1 : b.size())]);
  return d == 0 && !b.empty();
}

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(net::ip::tcp::socket&& socket, const ServerContext& ctx) : stream_(std::move(socket)), ctx_(ctx) {}

  void run() {
    net::dispatch(stream_.get_executor(), beast::bind_front_handler(&HttpSession::read, shared_from_this()));
  }

 private:
  void read() {
    request_ = {};
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, request_, beast::bind_front_handler(&HttpSession::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, size_t) {
    if (ec) {
      stream_.socket().shutdown(net::ip::tcp::socket::shutdown_send, ec);
      return;
    }
    const std::string target(request_.target());
    const size_t q = target.find('?');
    const std::string path = target.substr(0, q);
    const auto query = query_of(q == std::string::npos ? "" : target.substr(q + 1));
    if (path == "/ws") {
      if (!websocket::is_upgrade(request_)) return reply(400, "text/plain", "/ws is a WebSocket endpoint\n");
      const auto w = query.find("world");
      const std::string name = w == query.end() ? "" : w->second;
      std::shared_ptr<Room> room = ctx_.room(name);
      if (!room) {
        std::string names;
        for (const auto& r : ctx_.rooms) names += (names.empty() ? "" : ", ") + r->name();
        return reply(404, "text/plain", "no world '" + name + "' (worlds: " + names + ")\n");
      }
      const auto t = query.find("token");
      const bool can_command = t != query.end() && same_token(t->second, ctx_.options.token);
      // The protocol revision the client reads (docs/protocol.md, "Revisions"); clients older
      // than revision 4 give none.
      uint32_t revision = 0;
      if (const auto r = query.find("revision"); r != query.end()) {
        const std::string& v = r->second;
        if (v.empty() || v.size() > 9 || v.find_first_not_of("0123456789") != std::string::npos)
          return reply(400, "text/plain", "revision=" + v + ": not a whole number (the protocol revision the client reads)\n");
        revision = static_cast<uint32_t>(std::stoul(v));
      }
      stream_.expires_never();
      std::make_shared<WsSession>(stream_.release_socket(), std::move(room), can_command, revision, ctx_)
          ->run(std::move(request_));
      return;
    }
    if (request_.method() != http::verb::get && request_.method() != http::verb::head)
      return reply(405, "text/plain", "only GET\n");
    if (path == "/metrics") return reply(200, "application/json", metrics_json(ctx_));
    const StaticResponse r = static_file(ctx_, path);
    reply(r.status, r.content_type, r.body);
  }

  void reply(int status, const std::string& type, std::string body) {
    auto res = std::make_shared<http::response<http::string_body>>(static_cast<http::status>(status), request_.version());
    res->set(http::field::server, "cellphys serve");
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-store");
    res->keep_alive(request_.keep_alive());
    if (request_.method() != http::verb::head) res->body() = std::move(body);
    res->prepare_payload();
    http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code ec, size_t) {
      if (ec || !res->keep_alive()) {
        self->stream_.socket().shutdown(net::ip::tcp::socket::shutdown_send, ec);
        return;
      }
      self->read();
    });
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  http::request<http::string_body> request_;
  const ServerContext& ctx_;
};

}  // namespace

void serve_http(net::ip::tcp::socket&& socket, const ServerContext& ctx) {
  std::make_shared<HttpSession>(std::move(socket), ctx)->run();
}

}  // namespace cellphys::server
