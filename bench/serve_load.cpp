// The serving load benchmark (not a timed test): `cellphys serve SCENE` at 60 Hz with N
// WebSocket clients (Boost.Beast, each reading on a thread of its own) for S seconds; prints the
// server's tick rate, step time (median, p99), bytes per client per second, state messages
// skipped, and the server process's CPU time per second of wall time. With `reset`, one more
// connection resets the world every 2 s, so its bodies keep falling (a settled world1000 is
// asleep in 2 s and sends next to nothing). Arguments after `--` go to the server; with
// `--record FILE` among them, the recording's growth over the window is printed too (bytes a
// second), for the cost of recording.
//   serve_load CELLPHYS_EXE SCENES_DIR SCENE CLIENTS SECONDS [full|quantised] [settled|reset] [-- SERVE_ARGS...]
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "server/command.h"
#include "tests/support/serve_process.h"
#include "tests/support/ws_client.h"

namespace {

// utime + stime of a process, in seconds.
double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream s(text.substr(text.rfind(')') + 2));
  std::string field;
  double ut = 0, st = 0;
  for (int i = 3; i <= 15 && s >> field; ++i) {
    if (i == 14) ut = std::atof(field.c_str());
    if (i == 15) st = std::atof(field.c_str());
  }
  return (ut + st) / double(sysconf(_SC_CLK_TCK));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 6) {
    std::fprintf(stderr, "usage: serve_load CELLPHYS_EXE SCENES_DIR SCENE CLIENTS SECONDS [full|quantised] [settled|reset] [-- SERVE_ARGS...]\n");
    return 2;
  }
  const std::string exe = argv[1], scenes = argv[2], scene = argv[3];
  const int clients = std::atoi(argv[4]);
  const double seconds = std::atof(argv[5]);
  const bool quantised = argc > 6 && std::string(argv[6]) == "quantised";
  const bool stir = argc > 7 && std::string(argv[7]) == "reset";
  std::vector<std::string> serve_args = {scene};
  std::string record;
  for (int i = 6; i < argc; ++i)
    if (std::string(argv[i]) == "--") {
      for (int k = i + 1; k < argc; ++k) {
        serve_args.push_back(argv[k]);
        if (std::string(argv[k]) == "--record" && k + 1 < argc) record = argv[k + 1];
      }
      break;
    }
  auto recorded = [&]() -> double {
    std::error_code ec;
    return record.empty() ? 0.0 : double(std::filesystem::file_size(record, ec));
  };
  cellphys::test::ServeProcess server(exe, serve_args, scenes);
  std::atomic<bool> stop{false};
  std::thread stirrer;
  if (stir)
    stirrer = std::thread([&] {
      cellphys::test::WsClient ws(server.port(), "/ws?world=" + scene + "&revision=4&token=" + server.token());
      uint32_t seq = 0;
      auto next = std::chrono::steady_clock::now();
      while (!stop) {
        if (std::chrono::steady_clock::now() >= next) {
          cellphys::server::protocol::Control c{};
          c.seq = ++seq;
          const auto cmd = cellphys::server::make_command(cellphys::server::protocol::Type::reset, c);
          ws.send(cmd.bytes, cmd.size);
          next += std::chrono::seconds(2);
        }
        if (!ws.receive(std::chrono::seconds(2))) break;  // ticks come at 60 Hz: a reset is never late
      }
    });
  std::atomic<uint64_t> bytes{0}, messages{0};
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c)
    threads.emplace_back([&] {
      cellphys::test::WsClient ws(server.port(), "/ws?world=" + scene + "&revision=4");
      if (quantised) {
        cellphys::server::protocol::Subscribe s{};
        s.flags = cellphys::server::protocol::kSubscribeQuantised;
        const auto cmd = cellphys::server::make_command(cellphys::server::protocol::Type::subscribe, s);
        ws.send(cmd.bytes, cmd.size);
      }
      while (!stop) {
        auto m = ws.receive(std::chrono::milliseconds(500));
        if (!m) break;
        bytes += m->size();
        ++messages;
      }
    });
  // Measure after the joins, over the window.
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const uint64_t b0 = bytes;
  const double cpu0 = cpu_seconds(server.pid());
  const double rec0 = recorded();
  const auto t0 = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu = cpu_seconds(server.pid()) - cpu0;
  const double rec_rate = (recorded() - rec0) / wall;
  const uint64_t got = bytes - b0;
  const auto [status, body] = cellphys::test::http_get(server.port(), "/metrics");
  stop = true;
  for (std::thread& t : threads) t.join();
  if (stirrer.joinable()) stirrer.join();
  const nlohmann::json w = nlohmann::json::parse(body)["worlds"][0];
  std::printf("%s%s,%d,%s,%.1f,%.3f,%.3f,%.0f,%.3f,%llu,%llu", scene.c_str(), stir ? " (reset every 2 s)" : "", clients, quantised ? "quantised" : "full",
              w["tick_hz"].get<double>(), w["step_ms_median"].get<double>(), w["step_ms_p99"].get<double>(),
              double(got) / wall / std::max(1, clients), cpu / wall,
              static_cast<unsigned long long>(w["frames_skipped"].get<uint64_t>()),
              static_cast<unsigned long long>(w["late_ticks"].get<uint64_t>()));
  if (!record.empty()) std::printf(",%.0f", rec_rate);
  std::printf("\n");
  return status == 200 ? 0 : 1;
}
