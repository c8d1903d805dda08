// A room: one world served live, stepped on a thread of its own at a fixed real-time tick (or
// as fast as it can). Between steps it applies the commands clients submitted, in the order they
// arrived, answers each, records them, and publishes a Frame that its clients encode from. A
// world that throws is marked failed (reported in its metrics and to its clients) and stops
// stepping until reset; other rooms tick on regardless, as nothing is shared between them.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "server/command.h"
#include "server/frame.h"
#include "server/play_state.h"
#include "server/recording.h"
#include "server/state_encoder.h"
#include "server/watcher_stream.h"
#include "server/world_commands.h"

namespace cellphys::server {

/// A client as a room sees it: the room's thread hands it frames and replies; it must not block.
class ClientSink {
 public:
  virtual ~ClientSink() = default;
  virtual void on_frame(std::shared_ptr<const Frame> frame) = 0;
  /// An ack, error or status message.
  virtual void on_message(std::shared_ptr<const std::vector<unsigned char>> message) = 0;

  /// Bytes written to this client (counted by its session, on the network's threads).
  void count_sent(size_t n) { sent_.fetch_add(n, std::memory_order_relaxed); }
  uint64_t bytes_sent() const { return sent_.load(std::memory_order_relaxed); }
  /// Bytes a second over the room's last rate window (about 1 s), set by the room's thread.
  double bytes_per_s() const { return rate_.load(std::memory_order_relaxed); }
  void sample_rate(double dt_s) {
    const uint64_t now = bytes_sent();
    rate_.store(double(now - sampled_) / dt_s, std::memory_order_relaxed);
    sampled_ = now;
  }

 private:
  std::atomic<uint64_t> sent_{0};
  std::atomic<double> rate_{0};
  uint64_t sampled_ = 0;  // the room's thread's
};

struct RoomOptions {
  double tick_hz = 60;  // steps per real second
  bool fast = false;    // step as fast as possible
  std::string record;   // recording file, or none
  bool record_frames = true;  // the recording keeps the state messages sent (server/recording.h)
  bool record_debug = false;  // and a debug message a frame, so a recording shows the solver's overlays
  CommandLimits limits;
  // Test hooks (`cellphys serve --fault`): the step that would reach fault_throw_at throws (once);
  // every tick sleeps fault_slow_ms inside the step (a world under load).
  long long fault_throw_at = -1;
  double fault_slow_ms = 0;
};

struct RoomMetrics {
  std::string name, source, state, error, recording;
  uint64_t step = 0, state_hash = 0;
  double tick_hz_target = 0, tick_hz = 0;  // the target is the tick rate times the speed
  double speed = 1;                         // set_speed's: the pace against real time
  double step_ms_median = 0, step_ms_p99 = 0;
  std::vector<std::pair<const char*, double>> stage_ms_mean;
  uint32_t bodies = 0, bodies_awake = 0, bodies_asleep = 0;
  size_t clients = 0;
  std::vector<std::pair<uint64_t, double>> client_bytes;  // per client: bytes sent, bytes a second
  double bytes_sent_per_s = 0;
  uint64_t bytes_sent = 0, commands_accepted = 0, commands_refused = 0, frames_skipped = 0, clients_dropped = 0,
           late_ticks = 0, failed_islands = 0;
};

class Room {
 public:
  /// `world` is the scene as built (`source` names it); throws RecordingError if the recording
  /// cannot be created.
  Room(std::string name, std::string source, std::unique_ptr<ppe::World> world, RoomOptions options);
  ~Room();
  Room(const Room&) = delete;
  Room& operator=(const Room&) = delete;

  const std::string& name() const { return name_; }
  void start();
  /// Stops the thread and closes the recording (its end record). Idempotent.
  void stop();

  void attach(const std::shared_ptr<ClientSink>& client);
  void detach(const ClientSink* client);
  /// Queues a framed command for the next tick; the answer goes to `from`.
  void submit(const Command& c, std::weak_ptr<ClientSink> from);
  /// The newest published frame (never null once constructed).
  std::shared_ptr<const Frame> latest() const;
  /// The protocol revision a client must read to read this world's join (revision_needed of its
  /// dictionary, which no command or reset changes).
  const RevisionNeed& revision_needed() const { return revision_needed_; }
  RoomMetrics metrics() const;

  // Counted by the clients' sessions.
  void count_refused() { refused_.fetch_add(1, std::memory_order_relaxed); }
  void count_bytes(size_t n) { bytes_.fetch_add(n, std::memory_order_relaxed); }
  void count_skipped(uint32_t n) { skipped_.fetch_add(n, std::memory_order_relaxed); }
  void count_dropped() { dropped_.fetch_add(1, std::memory_order_release); }  // after detach(): metrics() acquires
  /// A client starts (+1) or stops (-1) wanting debug messages; frames carry one while any does.
  void count_debug(int delta) { debug_clients_.fetch_add(delta, std::memory_order_relaxed); }

 private:
  struct Pending {
    Command command;
    std::weak_ptr<ClientSink> from;
  };
  void run();
  void tick();
  void apply(const Pending& p, bool& changed);
  void step_world();
  void publish();
  void broadcast(std::shared_ptr<const std::vector<unsigned char>> message);
  void broadcast_status();
  std::vector<std::shared_ptr<ClientSink>> clients() const;

  const std::string name_, source_;
  const RoomOptions options_;
  WorldCommands commands_;
  std::unique_ptr<RecordingWriter> recorder_;
  WatcherStream recorded_;  // the state messages the recording keeps

  // The room thread's own state.
  PlayState play_;
  bool failed_ = false, fault_fired_ = false;
  std::string error_;
  uint64_t seq_ = 0;
  double last_step_ms_ = 0;
  std::shared_ptr<const std::vector<unsigned char>> shapes_;
  RevisionNeed revision_needed_;

  mutable std::mutex frame_mutex_;
  std::shared_ptr<const Frame> latest_;

  std::mutex queue_mutex_;
  std::vector<Pending> queue_;

  mutable std::mutex clients_mutex_;
  std::vector<std::weak_ptr<ClientSink>> clients_;

  // Metrics: a window of recent steps, under metrics_mutex_.
  struct StepSample {
    double at_s, ms;
    ppe::StageTimes times;
  };
  mutable std::mutex metrics_mutex_;
  std::deque<StepSample> window_;
  std::string state_ = "running", reported_error_;
  uint64_t failed_islands_ = 0, late_ticks_ = 0, accepted_ = 0;
  double bytes_rate_ = 0;
  std::atomic<int> debug_clients_{0};
  std::atomic<double> speed_{1.0};  // set by set_speed on the room's thread, read by metrics()
  std::atomic<uint64_t> refused_{0}, bytes_{0}, skipped_{0}, dropped_{0};

  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace cellphys::server
