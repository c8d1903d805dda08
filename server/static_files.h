// GET / and the files under it: the viewer's directory (a build of viewer/), or, when there is
// none, a small page that says so and lists the worlds.
#pragma once
#include <string>

#include "server/server_context.h"

namespace cellphys::server {

struct StaticResponse {
  int status = 200;
  std::string content_type, body;
};

/// The response to GET `path` (the target without its query).
StaticResponse static_file(const ServerContext& ctx, const std::string& path);

}  // namespace cellphys::server
