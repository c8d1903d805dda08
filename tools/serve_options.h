// `cellphys serve`'s options: what they hold, their help text, and the parser.
#pragma once
#include <string>
#include <vector>

#include "server/server_context.h"

namespace cellphys::cli {

struct ServeWorld {
  std::string name, scene;  // NAME=SCENE, or SCENE named after itself
  std::string record;       // recording file, or none
  long long fault_throw_at = -1;
  double fault_slow_ms = 0;
};

struct ServeOptions {
  std::vector<ServeWorld> worlds;  // at least one (the default world when none is given)
  server::ServerOptions server;
  double tick_hz = 60;
  bool fast = false;
  bool record_frames = true;  // recordings keep the state messages sent (server/recording.h)
  bool record_debug = false;  // and each frame's debug message
  int workers = 0;  // 0: the scene's
};

std::string serve_help();

/// Parses argv[1..argc) (argv[0] is the subcommand's name); false when --help was asked for.
/// Throws UsageError naming the option.
bool parse_serve_options(int argc, char** argv, ServeOptions& o);

}  // namespace cellphys::cli
