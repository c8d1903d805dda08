// The cellphys command's subcommands (tools/cellphys_main.cpp dispatches). Each takes its own
// arguments (argv[0] is the subcommand's name) and returns the exit code: 0 done, 1 failed
// while running, 2 usage or scene error.
#pragma once

namespace cellphys::cli {

int run_main(int argc, char** argv);          // cellphys run [SCENE] [options]
int scenes_main(int argc, char** argv);       // cellphys scenes
int kernel_demo_main(int argc, char** argv);  // cellphys kernel-demo
int serve_main(int argc, char** argv);        // cellphys serve [SCENE...] [options]
int replay_main(int argc, char** argv);       // cellphys replay FILE

}  // namespace cellphys::cli
