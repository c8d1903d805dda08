#include "server/room.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "server/debug_encoder.h"
#include "server/frame_builder.h"
#include "server/replies.h"
#include "server/state_encoder.h"

namespace cellphys::server {

namespace {

using Clock = std::chrono::steady_clock;
constexpr size_t kWindowSteps = 600;  // metrics over the last 600 steps (10 s at 60 Hz)

double now_s() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

Room::Room(std::string name, std::string source, std::unique_ptr<ppe::World> world, RoomOptions options)
    : name_(std::move(name)), source_(std::move(source)), options_(std::move(options)),
      commands_(world->snapshot(), options_.limits) {
  world.reset();
  shapes_ = std::make_shared<const std::vector<unsigned char>>(encode_shapes(commands_.world().shapes()));
  revision_needed_ = server::revision_needed(commands_.world().shapes());
  if (!options_.record.empty()) {
    recorder_ = std::make_unique<RecordingWriter>(options_.record, options_.record_frames,
                                                  options_.record_frames && options_.record_debug);
    recorder_->world(name_, commands_.initial_snapshot());
  }
  publish();
  if (recorder_) recorder_->flush();
}

Room::~Room() { stop(); }

void Room::start() {
  if (!thread_.joinable()) thread_ = std::thread([this] { run(); });
}

void Room::stop() {
  {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (recorder_) {
    const ppe::World& w = commands_.world();
    auto r = std::move(recorder_);
    try {
      r->close(w.last_stats().step, w.state_hash());
    } catch (const RecordingError& e) {
      std::fprintf(stderr, "cellphys serve: %s\n", e.what());
    }
  }
}

void Room::attach(const std::shared_ptr<ClientSink>& client) {
  std::lock_guard<std::mutex> lock(clients_mutex_);
  clients_.push_back(client);
}

void Room::detach(const ClientSink* client) {
  std::lock_guard<std::mutex> lock(clients_mutex_);
  clients_.erase(std::remove_if(clients_.begin(), clients_.end(),
                                [client](const std::weak_ptr<ClientSink>& w) {
                                  auto s = w.lock();
                                  return !s || s.get() == client;
                                }),
                 clients_.end());
}

std::vector<std::shared_ptr<ClientSink>> Room::clients() const {
  std::vector<std::shared_ptr<ClientSink>> out;
  std::lock_guard<std::mutex> lock(clients_mutex_);
  for (const auto& w : clients_)
    if (auto s = w.lock()) out.push_back(std::move(s));
  return out;
}

void Room::submit(const Command& c, std::weak_ptr<ClientSink> from) {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  queue_.push_back({c, std::move(from)});
}

std::shared_ptr<const Frame> Room::latest() const {
  std::lock_guard<std::mutex> lock(frame_mutex_);
  return latest_;
}

void Room::run() {
  auto next = Clock::now();
  double bytes_at = now_s();
  uint64_t bytes_then = bytes_.load();
  for (;;) {
    if (!options_.fast) {
      // set_speed paces the ticks: speed times the tick rate, each step of the world's dt.
      const auto period = std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(1.0 / (options_.tick_hz * speed_.load(std::memory_order_relaxed))));
      next += period;
      const auto now = Clock::now();
      if (now > next + period) {  // more than a tick behind: count it and keep the rhythm from now
        std::lock_guard<std::mutex> lock(metrics_mutex_);
        ++late_ticks_;
        next = now;
      }
      std::unique_lock<std::mutex> lock(stop_mutex_);
      if (stop_cv_.wait_until(lock, next, [this] { return stop_; })) return;
    } else {
      std::lock_guard<std::mutex> lock(stop_mutex_);
      if (stop_) return;
    }
    tick();
    const double t = now_s();
    if (t - bytes_at >= 1.0) {
      const uint64_t b = bytes_.load();
      std::lock_guard<std::mutex> lock(metrics_mutex_);
      bytes_rate_ = double(b - bytes_then) / (t - bytes_at);
      for (const auto& c : clients()) c->sample_rate(t - bytes_at);
      bytes_then = b;
      bytes_at = t;
    }
  }
}

void Room::tick() {
  std::vector<Pending> batch;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    batch.swap(queue_);
  }
  bool changed = false;
  for (const Pending& p : batch) apply(p, changed);
  if (!failed_ && play_.steps()) {
    step_world();
    play_.stepped();
    changed = true;
  }
  if (changed) publish();
  if (recorder_) recorder_->flush();
}

void Room::apply(const Pending& p, bool& changed) {
  const Command& c = p.command;
  auto reply = [&](Message m) {
    if (auto s = p.from.lock()) s->on_message(std::move(m));
  };
  const uint64_t step = commands_.world().last_stats().step;
  using protocol::Type;
  const auto type = static_cast<Type>(c.type);
  if (failed_ && type != Type::reset) {
    count_refused();
    reply(encode_error(c.seq, c.type,
                       {protocol::ErrorCode::world_failed, protocol::type_name(c.type),
                        "the world failed (" + error_ + "); only reset is accepted"}));
    return;
  }
  Applied a;
  if (auto e = commands_.apply(c, a)) {
    count_refused();
    reply(encode_error(c.seq, c.type, *e));
    return;
  }
  if (recorder_) recorder_->command(step, c);
  {
    std::lock_guard<std::mutex> lock(metrics_mutex_);
    ++accepted_;
  }
  const bool status = play_.applied(c.type);
  if (type == Type::reset) {
    failed_ = false;
    error_.clear();
  }
  if (type == Type::set_speed) speed_.store(c.as<protocol::SetSpeed>().speed, std::memory_order_relaxed);
  changed = true;
  reply(encode_ack(c, step, a.result));
  if (status) broadcast_status();
}

void Room::step_world() {
  ppe::World& w = commands_.world();
  const auto t0 = Clock::now();
  try {
    if (options_.fault_slow_ms > 0)
      std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(options_.fault_slow_ms));
    if (!fault_fired_ && options_.fault_throw_at >= 0 &&
        static_cast<long long>(w.last_stats().step) + 1 >= options_.fault_throw_at) {
      fault_fired_ = true;
      throw std::runtime_error("test fault: step " + std::to_string(options_.fault_throw_at) + " made to throw");
    }
    const ppe::StepStats& st = w.step();
    last_step_ms_ = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (recorder_) recorder_->hash(st.step, w.state_hash());
    std::lock_guard<std::mutex> lock(metrics_mutex_);
    window_.push_back({now_s(), last_step_ms_, st.times});
    if (window_.size() > kWindowSteps) window_.pop_front();
    failed_islands_ += st.failed_islands;
  } catch (const std::exception& e) {
    failed_ = true;
    error_ = e.what();
    broadcast_status();
  }
}

void Room::publish() {
  const ppe::World& w = commands_.world();
  FrameContext at;
  at.world = name_;
  at.seq = ++seq_;
  at.epoch = play_.epoch;
  at.paused = play_.paused;
  at.tick_hz = options_.fast ? 0.0f : static_cast<float>(options_.tick_hz);
  at.step_ms = last_step_ms_;
  at.shapes = shapes_;
  const std::shared_ptr<Frame> f = build_frame(w, at, latest().get());
  if (debug_clients_.load(std::memory_order_relaxed) > 0 || (recorder_ && recorder_->debug()))
    f->debug = std::make_shared<const std::vector<unsigned char>>(encode_debug(w, play_.epoch));
  if (recorder_ && recorder_->frames()) {
    recorder_->frame(f->step, *recorded_.next(*f));
    recorder_->frame(f->step, *f->stages);
    if (recorder_->debug()) recorder_->frame(f->step, *f->debug);
  }
  {
    std::lock_guard<std::mutex> lock(frame_mutex_);
    latest_ = f;
  }
  for (const auto& c : clients()) c->on_frame(f);
}

void Room::broadcast(Message message) {
  for (const auto& c : clients()) c->on_message(message);
}

void Room::broadcast_status() {
  const uint64_t step = commands_.world().last_stats().step;
  using protocol::WorldState;
  const WorldState s = failed_ ? WorldState::failed : play_.paused ? WorldState::paused : WorldState::running;
  {
    std::lock_guard<std::mutex> lock(metrics_mutex_);
    state_ = failed_ ? "failed" : play_.paused ? "paused" : "running";
    reported_error_ = error_;
  }
  broadcast(encode_status(s, step, error_));
}

RoomMetrics Room::metrics() const {
  RoomMetrics m;
  m.name = name_;
  m.source = source_;
  m.recording = options_.record;
  m.speed = speed_.load(std::memory_order_relaxed);
  m.tick_hz_target = options_.fast ? 0.0 : options_.tick_hz * m.speed;
  if (const auto f = latest()) {
    m.step = f->step;
    m.state_hash = f->state_hash;
    for (const FrameBody& b : f->bodies) {
      if (b.flags & protocol::kBodyStatic) continue;
      ++m.bodies;
      (b.flags & protocol::kBodyAwake ? m.bodies_awake : m.bodies_asleep)++;
    }
  }
  {
    std::lock_guard<std::mutex> lock(clients_mutex_);
    for (const auto& c : clients_) m.clients += !c.expired();
  }
  for (const auto& c : clients()) m.client_bytes.emplace_back(c->bytes_sent(), c->bytes_per_s());
  m.commands_refused = refused_.load();
  m.bytes_sent = bytes_.load();
  m.frames_skipped = skipped_.load();
  m.clients_dropped = dropped_.load(std::memory_order_acquire);
  std::lock_guard<std::mutex> lock(metrics_mutex_);
  m.state = state_;
  m.error = reported_error_;
  m.commands_accepted = accepted_;
  m.failed_islands = failed_islands_;
  m.late_ticks = late_ticks_;
  m.bytes_sent_per_s = bytes_rate_;
  std::vector<double> ms;
  ms.reserve(window_.size());
  for (const StepSample& s : window_) ms.push_back(s.ms);
  m.step_ms_median = percentile(ms, 0.5);
  m.step_ms_p99 = percentile(ms, 0.99);
  // Steps per second over the last 2 s of the window (0 when paused, failed or just started).
  const double t = now_s();
  size_t n = 0;
  double first = t;
  for (auto it = window_.rbegin(); it != window_.rend() && t - it->at_s <= 2.0; ++it, ++n) first = it->at_s;
  if (n >= 2 && t - first > 0) m.tick_hz = double(n) / (t - first);
  for (const ppe::StageTimeField& s : ppe::kStageTimeFields) {
    double sum = 0;
    for (const StepSample& w : window_) sum += w.times.*(s.ms);
    m.stage_ms_mean.emplace_back(s.name, window_.empty() ? 0.0 : sum / double(window_.size()));
  }
  return m;
}

}  // namespace cellphys::server
