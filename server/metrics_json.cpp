#include "server/metrics_json.h"

#include <cstdio>

#include <nlohmann/json.hpp>

namespace cellphys::server {

std::string metrics_json(const ServerContext& ctx) {
  using json = nlohmann::json;
  json worlds = json::array();
  for (const auto& room : ctx.rooms) {
    const RoomMetrics m = room->metrics();
    json stages = json::object();
    for (const auto& [name, ms] : m.stage_ms_mean) stages[name] = ms;
    json per_client = json::array();
    for (const auto& [sent, rate] : m.client_bytes) per_client.push_back({{"bytes_sent", sent}, {"bytes_sent_per_s", rate}});
    char hash[19];
    std::snprintf(hash, sizeof hash, "0x%016llx", static_cast<unsigned long long>(m.state_hash));
    json w = {
        {"name", m.name},
        {"source", m.source},
        {"state", m.state},
        {"error", m.error},
        {"step", m.step},
        {"state_hash", hash},
        {"tick_hz_target", m.tick_hz_target},
        {"speed", m.speed},
        {"tick_hz", m.tick_hz},
        {"step_ms_median", m.step_ms_median},
        {"step_ms_p99", m.step_ms_p99},
        {"stage_ms_mean", stages},
        {"bodies", m.bodies},
        {"bodies_awake", m.bodies_awake},
        {"bodies_asleep", m.bodies_asleep},
        {"clients", m.clients},
        {"per_client", per_client},
        {"bytes_sent", m.bytes_sent},
        {"bytes_sent_per_s", m.bytes_sent_per_s},
        {"commands_accepted", m.commands_accepted},
        {"commands_refused", m.commands_refused},
        {"frames_skipped", m.frames_skipped},
        {"clients_dropped", m.clients_dropped},
        {"late_ticks", m.late_ticks},
        {"failed_islands", m.failed_islands},
        {"recording", m.recording},
    };
    worlds.push_back(std::move(w));
  }
  const double uptime = std::chrono::duration<double>(std::chrono::steady_clock::now() - ctx.started).count();
  return json{{"uptime_s", uptime}, {"worlds", worlds}}.dump(2) + "\n";
}

}  // namespace cellphys::server
