#include "tools/serve_options.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "runtime/ppe/settings.h"
#include "tools/builtin_scenes.h"
#include "tools/option_values.h"
#include "tools/usage_error.h"

namespace cellphys::cli {

namespace {

const char kServeHelp[] =
    "usage: cellphys serve [[NAME=]SCENE ...] [options]\n"
    "\n"
    "Serves each SCENE (a scene file or a built-in scene; default: world1000) as a world of its\n"
    "own, stepped live on its own thread, to WebSocket clients (docs/protocol.md, docs/server.md).\n"
    "A world is named NAME, or after its scene. Prints `listening on http://ADDR:PORT/` and\n"
    "`token TOKEN`; watching needs no token, commands do (/ws?world=NAME&token=TOKEN). A client\n"
    "of a world with meshes, height fields or compounds says it reads revision 4 (&revision=4).\n"
    "\n"
    "options:\n"
    "  --host ADDR       address to listen on (default 127.0.0.1)\n"
    "  --port N          port (default 8080; 0 picks a free one)\n"
    "  --tick HZ         steps per real second (default 60)\n"
    "  --fast            step as fast as possible instead (for measurements)\n"
    "  --workers K       compute workers (threads) per world (default: the scene's)\n"
    "  --token TOKEN     the token commands need (default: a random one)\n"
    "  --viewer DIR      files served at / (default: the source tree's viewer/dist)\n"
    "  --record [WORLD=]FILE  record a world (default: the first) for `cellphys replay` and\n"
    "                    the viewer\n"
    "  --record-frames on|off  keep the state messages sent in recordings, for the viewer and\n"
    "                    replay's frame check (default on; off: commands and hashes only)\n"
    "  --record-debug on|off  keep each frame's debug message too (contacts with their forces,\n"
    "                    islands, cut couplings), so the viewer draws the solver's overlays\n"
    "                    from the recording (default off: about 40 bytes a contact a tick)\n"
    "  --rate N          commands a second a connection may send on average (default 60)\n"
    "  --burst N         and in a burst (default 120); beyond, refused with an error\n"
    "  --client-deadline S  drop a client whose write has not completed in S seconds (default 5)\n"
    "  --io-threads N    network threads (default 1)\n"
    "  --fault WORLD=throw@STEP|WORLD=slow@MS  test hook: that world's step STEP throws, or\n"
    "                    each of its ticks takes MS longer\n"
    "  -h, --help        this text\n"
    "\n"
    "Stops on SIGINT or SIGTERM (recordings are closed). Exit codes: 0 stopped, 1 failed, 2 a\n"
    "usage or scene error.\n";

// "NAME=REST" split at the first '=' (no name: "").
std::pair<std::string, std::string> named(const std::string& s) {
  const size_t eq = s.find('=');
  if (eq == std::string::npos) return {"", s};
  return {s.substr(0, eq), s.substr(eq + 1)};
}

ServeWorld* world_named(ServeOptions& o, const std::string& opt, const std::string& name) {
  if (name.empty()) return &o.worlds.front();
  for (ServeWorld& w : o.worlds)
    if (w.name == name) return &w;
  throw UsageError{opt + ": no world '" + name + "'"};
}

}  // namespace

std::string serve_help() { return kServeHelp; }

bool parse_serve_options(int argc, char** argv, ServeOptions& o) {
  std::vector<std::string> scenes;
  std::vector<std::pair<std::string, std::string>> records, faults;  // applied once the worlds are known
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i], value;
    const bool is_opt = arg.size() > 2 && arg[0] == '-' && arg[1] == '-';
    if (is_opt && arg.find('=') != std::string::npos && arg.rfind("--", 0) == 0) {
      value = arg.substr(arg.find('=') + 1);
      arg = arg.substr(0, arg.find('='));
      if (arg == "--fast" || arg == "--help") throw UsageError{arg + " takes no value"};
    } else if (is_opt && arg != "--fast" && arg != "--help") {
      if (i + 1 >= argc) throw UsageError{arg + " needs a value"};
      value = argv[++i];
    }
    if (arg == "-h" || arg == "--help") return false;
    if (!is_opt) {
      if (!arg.empty() && arg[0] == '-') throw UsageError{"unknown option '" + arg + "'"};
      scenes.push_back(arg);
    } else if (arg == "--host") {
      if (value.empty()) throw UsageError{"--host needs an address"};
      o.server.host = value;
    } else if (arg == "--port") {
      o.server.port = static_cast<unsigned short>(parse_count(arg, value, 0, 65535));
    } else if (arg == "--tick") {
      o.tick_hz = parse_number(arg, value, 1, 10000);
    } else if (arg == "--fast") {
      o.fast = true;
    } else if (arg == "--workers") {
      o.workers = static_cast<int>(parse_count(arg, value, 1, ppe::kMaxWorkers));
    } else if (arg == "--token") {
      if (value.size() < 8) throw UsageError{"--token needs at least 8 characters"};
      o.server.token = value;
    } else if (arg == "--viewer") {
      o.server.viewer_dir = value;
    } else if (arg == "--record") {
      const auto nv = named(value);
      if (nv.second.empty()) throw UsageError{"--record needs a file"};
      records.push_back(nv);
    } else if (arg == "--record-frames") {
      if (value != "on" && value != "off") throw UsageError{"--record-frames takes on or off, got '" + value + "'"};
      o.record_frames = value == "on";
    } else if (arg == "--record-debug") {
      if (value != "on" && value != "off") throw UsageError{"--record-debug takes on or off, got '" + value + "'"};
      o.record_debug = value == "on";
    } else if (arg == "--rate") {
      o.server.command_rate = parse_number(arg, value, 0.001, 1e6);
    } else if (arg == "--burst") {
      o.server.command_burst = parse_number(arg, value, 1, 1e6);
    } else if (arg == "--client-deadline") {
      o.server.client_deadline_s = parse_number(arg, value, 0.01, 3600);
    } else if (arg == "--io-threads") {
      o.server.io_threads = static_cast<int>(parse_count(arg, value, 1, 64));
    } else if (arg == "--fault") {
      faults.push_back(named(value));
    } else {
      throw UsageError{"unknown option '" + arg + "'"};
    }
  }
  if (o.record_debug && !o.record_frames)
    throw UsageError{"--record-debug on keeps a debug message with each recorded frame: it needs --record-frames on"};
  if (scenes.empty()) scenes.push_back(kDefaultScene);
  for (const std::string& s : scenes) {
    auto [name, scene] = named(s);
    if (scene.empty()) throw UsageError{"'" + s + "': no scene after the name"};
    if (name.empty()) name = std::filesystem::path(scene).stem().string();
    for (const ServeWorld& w : o.worlds)
      if (w.name == name) throw UsageError{"two worlds named '" + name + "' (name one NAME=SCENE)"};
    for (char c : name)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.'))
        throw UsageError{"world name '" + name + "': use letters, digits, '_', '-' and '.'"};
    ServeWorld w;
    w.name = name;
    w.scene = scene;
    o.worlds.push_back(w);
  }
  for (const auto& [name, file] : records) world_named(o, "--record", name)->record = file;
  for (const auto& [name, spec] : faults) {
    ServeWorld* w = world_named(o, "--fault", name);
    const size_t at = spec.find('@');
    const std::string kind = spec.substr(0, at);
    if (at == std::string::npos || (kind != "throw" && kind != "slow"))
      throw UsageError{"--fault takes WORLD=throw@STEP or WORLD=slow@MS, got '" + spec + "'"};
    if (kind == "throw") w->fault_throw_at = parse_count("--fault", spec.substr(at + 1), 1, 1000000000LL);
    else w->fault_slow_ms = parse_number("--fault", spec.substr(at + 1), 0, 60000);
  }
  return true;
}

}  // namespace cellphys::cli
