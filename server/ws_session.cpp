#include "server/ws_session.h"

#include <boost/asio/dispatch.hpp>
#include <cmath>
#include <cstring>
#include <boost/asio/post.hpp>

#include "server/command.h"
#include "server/replies.h"

namespace cellphys::server {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;

namespace {

constexpr size_t kMaxControl = 4096;         // answers waiting for a client that does not read
constexpr size_t kMaxClientMessage = 4096;   // bytes; the largest client message is 80
constexpr double kAbuseBursts = 10;          // refusals in a row, in bursts, before the connection is closed

}  // namespace

WsSession::WsSession(net::ip::tcp::socket&& socket, std::shared_ptr<Room> room, bool can_command, uint32_t revision,
                     const ServerContext& ctx)
    : ws_(std::move(socket)), deadline_timer_(ws_.get_executor()), room_(std::move(room)), ctx_(ctx),
      can_command_(can_command), revision_(revision), limiter_(ctx.options.command_rate, ctx.options.command_burst) {}

WsSession::~WsSession() {
  if (interest_.debug) room_->count_debug(-1);
  room_->detach(this);
}

void WsSession::drop() {
  // Off the room's client list before it is counted: whoever sees the count sees it gone (the
  // session itself lives on until its pending handlers finish).
  room_->detach(this);
  room_->count_dropped();
}

void WsSession::run(http::request<http::string_body> request) {
  net::dispatch(ws_.get_executor(), [self = shared_from_this(), req = std::move(request)]() mutable {
    self->ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    self->ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "cellphys serve"); }));
    self->ws_.read_message_max(kMaxClientMessage);
    beast::get_lowest_layer(self->ws_).expires_never();  // the websocket's own timeouts from here
    auto* ws = &self->ws_;
    ws->async_accept(req, beast::bind_front_handler(&WsSession::on_accept, self));
  });
}

void WsSession::on_accept(beast::error_code ec) {
  if (ec) return;
  open_ = true;
  ws_.binary(true);
  // A client that gives no revision predates revision 4, the first that asks for it.
  if ((revision_ ? revision_ : 3u) < room_->revision_needed().revision) return refuse_revision();
  room_->attach(shared_from_this());
  pending_ = room_->latest();  // the join
  maybe_write();
  do_read();
  watch_deadline();
}

// A client of an older revision reads a ShapeRecord's data only after a hull: it would take a
// mesh's, a height field's or a compound's for records and misread the rest of the join. It is
// sent an error message instead (a layout every revision reads), then closed; it never joins.
void WsSession::refuse_revision() {
  const RevisionNeed& need = room_->revision_needed();
  const std::string want = std::to_string(need.revision);
  const std::string said = revision_ ? "this connection reads revision " + std::to_string(revision_)
                                     : "this connection gave no revision (a client older than revision 4)";
  closed_ = true;  // nothing else is sent, and what the client sends is not read
  writing_ = encode_error(
      0, static_cast<uint16_t>(protocol::Type::join),
      CommandError{protocol::ErrorCode::invalid, "revision",
                   "world '" + room_->name() + "' holds a " + spu::shape_type_name(need.type) + " (shape " +
                       std::to_string(need.shape) + "), which only a client of protocol revision " + want +
                       " or later reads; " + said + ". A client that reads it connects with /ws?world=NAME&revision=" + want});
  ws_.async_write(net::buffer(*writing_), [self = shared_from_this(), want](beast::error_code ec, size_t bytes) {
    self->writing_.reset();
    if (ec) return;
    self->count_sent(bytes);
    self->ws_.async_close(websocket::close_reason(websocket::close_code::policy_error, "protocol revision " + want + " needed"),
                          [self](beast::error_code) {});
  });
}

void WsSession::do_read() {
  ws_.async_read(read_buffer_, beast::bind_front_handler(&WsSession::on_read, shared_from_this()));
}

void WsSession::on_read(beast::error_code ec, size_t) {
  if (ec) {
    closed_ = true;
    deadline_timer_.cancel();
    return;
  }
  if (!ws_.got_binary()) {
    refuse(0, 0, protocol::ErrorCode::malformed, "message", "a text message; the protocol's messages are binary");
  } else {
    const auto data = read_buffer_.cdata();
    handle(static_cast<const unsigned char*>(data.data()), data.size());
  }
  read_buffer_.consume(read_buffer_.size());
  if (!closed_) do_read();
}

void WsSession::refuse(uint32_t seq, uint16_t type, protocol::ErrorCode code, std::string field, std::string reason) {
  room_->count_refused();
  on_message(encode_error(seq, type, CommandError{code, std::move(field), std::move(reason)}));
}

void WsSession::handle(const unsigned char* data, size_t size) {
  Command c;
  CommandError err;
  if (!decode_client_message(data, size, c, err)) {
    uint16_t type = 0;
    if (size >= 6) std::memcpy(&type, data + 4, 2);
    refuse(0, type, err.code, err.field, err.reason);
    return;
  }
  if (c.type == static_cast<uint16_t>(protocol::Type::subscribe)) {
    const auto s = c.as<protocol::Subscribe>();
    Interest next;
    next.quantised = (s.flags & protocol::kSubscribeQuantised) != 0;
    next.region = (s.flags & protocol::kSubscribeRegion) != 0;
    next.debug = (s.flags & protocol::kSubscribeDebug) != 0;
    next.stages = (s.flags & protocol::kSubscribeStages) != 0;
    if (next.region) {
      for (int k = 0; k < 3; ++k) {
        const std::string axis = "[" + std::to_string(k) + "]";
        if (!std::isfinite(s.min[k])) return refuse(0, c.type, protocol::ErrorCode::invalid, "subscribe.min" + axis, "not a finite number");
        if (!std::isfinite(s.max[k])) return refuse(0, c.type, protocol::ErrorCode::invalid, "subscribe.max" + axis, "not a finite number");
        if (s.min[k] > s.max[k])
          return refuse(0, c.type, protocol::ErrorCode::invalid, "subscribe.max" + axis, "is less than min" + axis);
        next.min[k] = s.min[k];
        next.max[k] = s.max[k];
      }
    }
    if (next.region || interest_.region) synced_full_ = false;  // the held set is no longer a frame's
    if (next.debug != interest_.debug) room_->count_debug(next.debug ? 1 : -1);
    interest_ = next;
    // The client sees the change at the next published state.
    return;
  }
  if (!can_command_)
    return refuse(c.seq, c.type, protocol::ErrorCode::unauthorized, "token",
                  "this connection gave no token (or a wrong one): watching needs none, commands need the server's "
                  "(/ws?world=NAME&token=TOKEN)");
  if (!limiter_.take()) {
    ++refused_in_a_row_;
    refuse(c.seq, c.type, protocol::ErrorCode::rate_limited, "rate",
           "more than " + std::to_string(static_cast<long>(ctx_.options.command_rate)) +
               " commands a second (bursts of " + std::to_string(static_cast<long>(ctx_.options.command_burst)) +
               "): refused");
    if (double(refused_in_a_row_) > kAbuseBursts * ctx_.options.command_burst) close(websocket::close_code::policy_error);
    return;
  }
  refused_in_a_row_ = 0;
  room_->submit(c, weak_from_this());
}

void WsSession::on_frame(std::shared_ptr<const Frame> frame) {
  net::post(ws_.get_executor(), [self = shared_from_this(), f = std::move(frame)]() mutable {
    if (self->closed_) return;
    if (self->pending_ && self->joined_) {
      ++self->skipped_;
      self->room_->count_skipped(1);
    }
    self->pending_ = std::move(f);
    self->maybe_write();
  });
}

void WsSession::on_message(std::shared_ptr<const std::vector<unsigned char>> message) {
  net::post(ws_.get_executor(), [self = shared_from_this(), m = std::move(message)]() mutable {
    if (self->closed_) return;
    if (self->control_.size() >= kMaxControl) {  // answers pile up: the client is not reading
      self->drop();
      self->close(websocket::close_code::policy_error);
      return;
    }
    self->control_.push_back(std::move(m));
    self->maybe_write();
  });
}

std::shared_ptr<const std::vector<unsigned char>> WsSession::encode(const Frame& f) {
  if (!joined_ || f.epoch != epoch_) {
    auto out = std::make_shared<std::vector<unsigned char>>();
    encode_join(f, interest_, can_command_, known_, *out);
    joined_ = true;
    synced_full_ = !interest_.region;
    epoch_ = f.epoch;
    last_seq_ = f.seq;
    skipped_ = 0;
    return out;
  }
  std::shared_ptr<const std::vector<unsigned char>> out;
  if (!interest_.region && synced_full_) {
    out = shared_tick(f, interest_.quantised, last_seq_, known_);
    if (skipped_) {
      auto copy = std::make_shared<std::vector<unsigned char>>(*out);
      set_skipped(*copy, skipped_);
      out = copy;
    }
  } else {
    auto mine = std::make_shared<std::vector<unsigned char>>();
    encode_tick(f, interest_, last_seq_, skipped_, known_, *mine);
    out = mine;
    synced_full_ = !interest_.region;
  }
  last_seq_ = f.seq;
  skipped_ = 0;
  return out;
}

void WsSession::maybe_write() {
  if (!open_ || closed_ || writing_) return;
  if (!follow_.empty()) {  // the stages and debug messages follow their tick
    writing_ = std::move(follow_.front());
    follow_.pop_front();
  } else if (!control_.empty()) {
    writing_ = std::move(control_.front());
    control_.pop_front();
  } else if (pending_) {
    const std::shared_ptr<const Frame> f = std::move(pending_);
    pending_.reset();
    if (joined_ && f->seq <= last_seq_ && f->epoch == epoch_) return;  // already sent
    writing_ = encode(*f);
    if (interest_.stages && f->stages) follow_.push_back(f->stages);
    if (interest_.debug && f->debug) follow_.push_back(f->debug);
  } else {
    return;
  }
  write_started_ = std::chrono::steady_clock::now();
  ws_.async_write(net::buffer(*writing_), beast::bind_front_handler(&WsSession::on_write, shared_from_this()));
}

void WsSession::on_write(beast::error_code ec, size_t bytes) {
  writing_.reset();
  if (ec) {
    closed_ = true;
    deadline_timer_.cancel();
    return;
  }
  room_->count_bytes(bytes);
  count_sent(bytes);
  maybe_write();
}

void WsSession::watch_deadline() {
  deadline_timer_.expires_after(std::chrono::milliseconds(250));
  deadline_timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
    if (ec || self->closed_) return;
    const auto stuck = std::chrono::steady_clock::now() - self->write_started_;
    if (self->writing_ && std::chrono::duration<double>(stuck).count() > self->ctx_.options.client_deadline_s) {
      self->drop();
      self->closed_ = true;
      beast::error_code ignored;
      beast::get_lowest_layer(self->ws_).socket().close(ignored);  // it does not read: no close handshake
      return;
    }
    self->watch_deadline();
  });
}

void WsSession::close(websocket::close_code code) {
  if (closed_) return;
  closed_ = true;
  deadline_timer_.cancel();
  ws_.async_close(code, [self = shared_from_this()](beast::error_code) {});
}

}  // namespace cellphys::server
