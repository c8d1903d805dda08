// `cellphys serve`: builds each world from its scene, makes it a room, and serves them
// (server/server.h) until SIGINT or SIGTERM.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "runtime/scene/scene.h"
#include "server/server.h"
#include "server/spawn_shapes.h"
#include "tools/builtin_scenes.h"
#include "tools/cli.h"
#include "tools/serve_options.h"
#include "tools/usage_error.h"

#ifndef CELLPHYS_VIEWER_DIR
#define CELLPHYS_VIEWER_DIR ""
#endif

namespace cellphys::cli {

namespace {

std::shared_ptr<server::Room> make_room(const ServeOptions& o, const ServeWorld& w) {
  const std::string file = resolve_scene(w.scene);
  scene::SceneDesc desc = scene::load_scene(file);
  if (o.workers > 0) desc.settings.workers = o.workers;
  scene::BuiltScene built = scene::build_world(desc);
  server::add_spawn_shapes(built.world->shapes());
  for (const std::string& warning : built.warnings) std::fprintf(stderr, "cellphys: %s: warning: %s\n", w.name.c_str(), warning.c_str());
  server::RoomOptions ro;
  ro.tick_hz = o.tick_hz;
  ro.fast = o.fast;
  ro.record = w.record;
  ro.record_frames = o.record_frames;
  ro.record_debug = o.record_debug;
  ro.fault_throw_at = w.fault_throw_at;
  ro.fault_slow_ms = w.fault_slow_ms;
  auto room = std::make_shared<server::Room>(w.name, file, std::move(built.world), ro);
  std::fprintf(stderr, "cellphys serve: world %s: %s, %zu bodies%s%s\n", w.name.c_str(), file.c_str(),
               room->latest()->bodies.size(), w.record.empty() ? "" : ", recording to ", w.record.c_str());
  return room;
}

}  // namespace

int serve_main(int argc, char** argv) {
  ServeOptions o;
  try {
    if (!parse_serve_options(argc, argv, o)) {
      std::fputs(serve_help().c_str(), stdout);
      return 0;
    }
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cellphys serve: %s\n(`cellphys serve --help` lists the options)\n", e.message.c_str());
    return 2;
  }
  if (o.server.viewer_dir.empty()) o.server.viewer_dir = CELLPHYS_VIEWER_DIR;
  std::vector<std::shared_ptr<server::Room>> rooms;
  try {
    for (const ServeWorld& w : o.worlds) rooms.push_back(make_room(o, w));
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cellphys serve: %s\n", e.message.c_str());
    return 2;
  } catch (const scene::SceneError& e) {
    std::fprintf(stderr, "cellphys: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cellphys serve: %s\n", e.what());
    return 1;
  }
  try {
    server::Server srv(o.server, rooms);
    std::printf("listening on http://%s:%u/\ntoken %s\n", srv.host().c_str(), static_cast<unsigned>(srv.port()),
                srv.token().c_str());
    std::fflush(stdout);
    srv.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cellphys serve: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "cellphys serve: stopped\n");
  return 0;
}

}  // namespace cellphys::cli
