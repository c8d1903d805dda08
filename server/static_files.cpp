#include "server/static_files.h"

#include <filesystem>
#include <fstream>
#include <iterator>

namespace cellphys::server {

namespace {

namespace fs = std::filesystem;

const char* content_type(const fs::path& p) {
  const std::string e = p.extension().string();
  if (e == ".html" || e == ".htm") return "text/html; charset=utf-8";
  if (e == ".js" || e == ".mjs") return "text/javascript; charset=utf-8";
  if (e == ".css") return "text/css; charset=utf-8";
  if (e == ".json" || e == ".map") return "application/json";
  if (e == ".svg") return "image/svg+xml";
  if (e == ".png") return "image/png";
  if (e == ".wasm") return "application/wasm";
  if (e == ".ico") return "image/x-icon";
  return "application/octet-stream";
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else out += c;
  }
  return out;
}

StaticResponse no_viewer(const ServerContext& ctx) {
  std::string worlds;
  for (const auto& r : ctx.rooms) worlds += "<li><code>/ws?world=" + escape(r->name()) + "</code></li>";
  const std::string where = ctx.options.viewer_dir.empty() ? "none given" : escape(ctx.options.viewer_dir);
  return {200, "text/html; charset=utf-8",
          "<!doctype html><html><head><meta charset=\"utf-8\"><title>cellphys serve</title></head><body>"
          "<h1>cellphys serve</h1><p>No viewer is built here (viewer directory: " + where +
              "; build viewer/ into viewer/dist, or pass <code>--viewer DIR</code>).</p>"
              "<p>Worlds (WebSocket, binary protocol: docs/protocol.md):</p><ul>" + worlds +
              "</ul><p><a href=\"/metrics\">/metrics</a></p></body></html>\n"};
}

}  // namespace

StaticResponse static_file(const ServerContext& ctx, const std::string& path) {
  std::error_code ec;
  const std::string& root = ctx.options.viewer_dir;
  if (root.empty() || !fs::is_directory(root, ec)) {
    if (path == "/" || path == "/index.html") return no_viewer(ctx);
    return {404, "text/plain; charset=utf-8", "not found: " + path + "\n"};
  }
  // Only plain names under the root: no "..", no empty or dot segments.
  fs::path rel;
  size_t at = 1;
  while (at <= path.size()) {
    const size_t end = std::min(path.find('/', at), path.size());
    const std::string seg = path.substr(at, end - at);
    if (seg == ".." || seg == "." || seg.find('\\') != std::string::npos || seg.find('\0') != std::string::npos)
      return {400, "text/plain; charset=utf-8", "bad path: " + path + "\n"};
    if (!seg.empty()) rel /= seg;
    at = end + 1;
  }
  fs::path file = fs::path(root) / rel;
  if (fs::is_directory(file, ec)) file /= "index.html";
  std::ifstream in(file, std::ios::binary);
  if (!in) return {404, "text/plain; charset=utf-8", "not found: " + path + "\n"};
  return {200, content_type(file), std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>())};
}

}  // namespace cellphys::server
