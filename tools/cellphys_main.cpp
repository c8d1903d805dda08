// The cellphys command: `cellphys run [SCENE]` steps a scene file (or a built-in scene) in the
// world and reports; `cellphys scenes` lists the built-in scenes; `cellphys kernel-demo` is the
// compute kernel alone; `cellphys serve` serves worlds live to WebSocket clients and `cellphys
// replay` re-runs a recording of one. No arguments (or only run's options) means `cellphys run`.
#include <cstdio>
#include <cstring>
#include <string>

#include "tools/cli.h"

namespace {

const char kHelp[] =
    "usage: cellphys [COMMAND] [ARGS]\n"
    "\n"
    "commands:\n"
    "  run [SCENE] [options]   step a scene and report (the default command; with no SCENE,\n"
    "                          the built-in default world 'world1000')\n"
    "  scenes                  list the built-in scenes with their descriptions\n"
    "  serve [SCENE...] [options]  serve worlds live over WebSocket (docs/server.md)\n"
    "  replay FILE             re-run a recording of `serve --record` and check its state hashes\n"
    "  kernel-demo [options]   the compute kernel alone: the reference design's 65-box group\n"
    "                          and a spinning box (no world)\n"
    "  help                    this text; `cellphys COMMAND --help` for a command's options\n"
    "\n"
    "Scene files are JSON (docs/scene-format.md); built-in scenes live in examples/scenes\n"
    "(override the directory with CELLPHYS_SCENES).\n";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return cellphys::cli::run_main(argc, argv);
  const std::string cmd = argv[1];
  if (cmd == "run") return cellphys::cli::run_main(argc - 1, argv + 1);
  if (cmd == "serve") return cellphys::cli::serve_main(argc - 1, argv + 1);
  if (cmd == "replay") return cellphys::cli::replay_main(argc - 1, argv + 1);
  if (cmd == "scenes") return cellphys::cli::scenes_main(argc - 1, argv + 1);
  if (cmd == "kernel-demo" || cmd == "demo") return cellphys::cli::kernel_demo_main(argc - 1, argv + 1);
  if (cmd == "help" || cmd == "-h" || cmd == "--help") {
    std::fputs(kHelp, stdout);
    return 0;
  }
  if (!cmd.empty() && cmd[0] == '-') return cellphys::cli::run_main(argc, argv);  // `cellphys --steps 10`
  std::fprintf(stderr, "cellphys: unknown command '%s'\n\n%s", cmd.c_str(), kHelp);
  return 2;
}
