#include "runtime/scene/obj_file.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace cellphys::scene {

namespace {

[[noreturn]] void fail(const std::string& name, size_t line, const std::string& why) {
  throw ObjError(name + ":" + std::to_string(line) + ": " + why);
}

// A face corner: its vertex index, before any '/', 1-based or negative (from the end so far).
int32_t corner(const std::string& word, size_t vertices, const std::string& name, size_t line) {
  const std::string v = word.substr(0, word.find('/'));
  char* end = nullptr;
  errno = 0;
  const long long i = std::strtoll(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || errno) fail(name, line, "face corner '" + word + "' is not a vertex index");
  const long long at = i > 0 ? i - 1 : static_cast<long long>(vertices) + i;
  if (i == 0 || at < 0 || at >= static_cast<long long>(vertices))
    fail(name, line, "face corner " + v + " names no vertex (" + std::to_string(vertices) + " so far)");
  return static_cast<int32_t>(at);
}

}  // namespace

ObjMesh parse_obj(const std::string& text, const std::string& name) {
  ObjMesh m;
  std::istringstream in(text);
  std::string row;
  size_t line = 0;
  while (std::getline(in, row)) {
    ++line;
    if (!row.empty() && row.back() == '\r') row.pop_back();
    std::istringstream words(row);
    std::string tag;
    if (!(words >> tag) || tag[0] == '#') continue;
    if (tag == "v") {
      float xyz[3];
      for (float& c : xyz) {
        std::string w;
        if (!(words >> w)) fail(name, line, "a vertex needs x, y and z");
        char* end = nullptr;
        c = std::strtof(w.c_str(), &end);
        if (*end != '\0' || !std::isfinite(c)) fail(name, line, "vertex coordinate '" + w + "' is not a finite number");
      }
      m.vertices.insert(m.vertices.end(), xyz, xyz + 3);
    } else if (tag == "f") {
      std::vector<int32_t> face;
      for (std::string w; words >> w;) face.push_back(corner(w, m.vertices.size() / 3, name, line));
      if (face.size() < 3) fail(name, line, "a face needs at least 3 corners");
      for (size_t k = 1; k + 1 < face.size(); ++k) m.triangles.insert(m.triangles.end(), {face[0], face[k], face[k + 1]});
    }
  }
  if (m.triangles.empty()) throw ObjError(name + ": no faces");
  return m;
}

ObjMesh load_obj(const std::string& path) {
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ObjError(path + ": cannot open: " + (errno ? std::strerror(errno) : "unknown error"));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ObjError(path + ": read error");
  return parse_obj(text.str(), path);
}

}  // namespace cellphys::scene
