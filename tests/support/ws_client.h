// A WebSocket client for the server's tests and benchmark, on Boost.Beast (the library the
// server uses): connect to /ws?..., send binary messages, receive them with a timeout; and
// an HTTP GET (for /metrics).
#pragma once
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <optional>
#include <string>
#include <vector>

namespace cellphys::test {

class WsClient {
 public:
  /// Connects to 127.0.0.1:port and opens `target` (e.g. "/ws?world=pile65"). A receive buffer
  /// of `rcvbuf` bytes (0: the system's) makes a client that fills up fast when it stops reading.
  WsClient(unsigned short port, const std::string& target, int rcvbuf = 0) : ws_(ioc_) {
    boost::asio::ip::tcp::endpoint at(boost::asio::ip::make_address("127.0.0.1"), port);
    auto& sock = boost::beast::get_lowest_layer(ws_);
    sock.open(at.protocol());
    if (rcvbuf > 0) sock.set_option(boost::asio::socket_base::receive_buffer_size(rcvbuf));
    sock.connect(at);
    ws_.handshake("127.0.0.1:" + std::to_string(port), target);
    ws_.binary(true);
  }

  void send(const void* data, size_t n) { ws_.write(boost::asio::buffer(data, n)); }
  template <class T>
  void send(const T& message) {
    send(&message, sizeof message);
  }

  /// The next message, or nothing if none comes within `timeout` or the connection closed
  /// (closed() tells which).
  std::optional<std::vector<unsigned char>> receive(std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    if (closed_) return std::nullopt;
    bool done = false;
    boost::beast::error_code result;
    buffer_.clear();
    ws_.async_read(buffer_, [&](boost::beast::error_code ec, size_t) {
      done = true;
      result = ec;
    });
    ioc_.restart();
    ioc_.run_for(timeout);
    if (!done) {
      boost::beast::get_lowest_layer(ws_).cancel();
      ioc_.restart();
      ioc_.run();
      closed_ = true;  // a cancelled read leaves the stream unusable
      timed_out_ = true;
      return std::nullopt;
    }
    if (result) {
      closed_ = true;
      return std::nullopt;
    }
    const auto d = buffer_.cdata();
    const auto* p = static_cast<const unsigned char*>(d.data());
    return std::vector<unsigned char>(p, p + d.size());
  }
  bool closed() const { return closed_; }
  bool timed_out() const { return timed_out_; }

 private:
  boost::asio::io_context ioc_;
  boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_;
  boost::beast::flat_buffer buffer_;
  bool closed_ = false, timed_out_ = false;
};

/// GET http://127.0.0.1:port/target: the status and body.
inline std::pair<int, std::string> http_get(unsigned short port, const std::string& target) {
  namespace http = boost::beast::http;
  boost::asio::io_context ioc;
  boost::asio::ip::tcp::socket sock(ioc);
  sock.connect({boost::asio::ip::make_address("127.0.0.1"), port});
  http::request<http::empty_body> req{http::verb::get, target, 11};
  req.set(http::field::host, "127.0.0.1");
  http::write(sock, req);
  boost::beast::flat_buffer buf;
  http::response<http::string_body> res;
  http::read(sock, buf, res);
  return {static_cast<int>(res.result_int()), res.body()};
}

}  // namespace cellphys::test
