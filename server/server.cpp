#include "server/server.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/strand.hpp>
#include <csignal>
#include <random>
#include <stdexcept>
#include <thread>

#include "server/http_session.h"

namespace cellphys::server {

namespace net = boost::asio;
using tcp = net::ip::tcp;

std::string random_token() {
  std::random_device rd;
  static const char kHex[] = "0123456789abcdef";
  std::string t;
  for (int i = 0; i < 4; ++i) {
    uint32_t v = rd();
    for (int k = 0; k < 8; ++k, v >>= 4) t += kHex[v & 15u];
  }
  return t;
}

struct Server::Impl {
  ServerContext ctx;
  net::io_context ioc;
  tcp::acceptor acceptor{ioc};
  net::signal_set signals{ioc, SIGINT, SIGTERM};

  void accept() {
    acceptor.async_accept(net::make_strand(ioc), [this](boost::system::error_code ec, tcp::socket socket) {
      if (ec) {
        if (ec == net::error::operation_aborted) return;
      } else {
        socket.set_option(tcp::no_delay(true), ec);
        // A fixed send buffer, not the system's autotuned one (megabytes): what a client that stops
        // reading can hold is bounded, and its writes stall soon enough for the deadline to drop it.
        socket.set_option(net::socket_base::send_buffer_size(ctx.options.client_send_buffer), ec);
        serve_http(std::move(socket), ctx);
      }
      accept();
    });
  }
};

Server::Server(ServerOptions options, std::vector<std::shared_ptr<Room>> rooms) : impl_(std::make_unique<Impl>()) {
  if (options.token.empty()) options.token = random_token();
  if (options.io_threads < 1) options.io_threads = 1;
  impl_->ctx.options = std::move(options);
  impl_->ctx.rooms = std::move(rooms);
  const ServerOptions& o = impl_->ctx.options;
  boost::system::error_code ec;
  const auto address = net::ip::make_address(o.host, ec);
  if (ec) throw std::runtime_error("--host " + o.host + ": not an IP address (" + ec.message() + ")");
  const tcp::endpoint at(address, o.port);
  tcp::acceptor& a = impl_->acceptor;
  const std::string where = o.host + ":" + std::to_string(o.port);
  if (a.open(at.protocol(), ec), ec) throw std::runtime_error("cannot open a socket for " + where + ": " + ec.message());
  a.set_option(net::socket_base::reuse_address(true), ec);
  if (a.bind(at, ec), ec) throw std::runtime_error("cannot listen on " + where + ": " + ec.message());
  if (a.listen(net::socket_base::max_listen_connections, ec), ec)
    throw std::runtime_error("cannot listen on " + where + ": " + ec.message());
}

Server::~Server() { stop(); }

unsigned short Server::port() const { return impl_->acceptor.local_endpoint().port(); }
const std::string& Server::host() const { return impl_->ctx.options.host; }
const std::string& Server::token() const { return impl_->ctx.options.token; }

void Server::run() {
  for (const auto& r : impl_->ctx.rooms) r->start();
  impl_->signals.async_wait([this](boost::system::error_code, int) { impl_->ioc.stop(); });
  impl_->accept();
  std::vector<std::thread> more;
  for (int i = 1; i < impl_->ctx.options.io_threads; ++i) more.emplace_back([this] { impl_->ioc.run(); });
  impl_->ioc.run();
  impl_->ioc.stop();
  for (std::thread& t : more) t.join();
  for (const auto& r : impl_->ctx.rooms) r->stop();
}

void Server::stop() { impl_->ioc.stop(); }

}  // namespace cellphys::server
