// Scene files as JSON: a strict reader (every field known, typed, finite, in range where the
// file alone can tell) and a writer whose output reads back to an equal SceneDesc.
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cellphys/gen/force_table.h"
#include "runtime/base/enum_names.h"
#include "runtime/ppe/settings.h"
#include "runtime/scene/obj_file.h"
#include "runtime/scene/scene.h"

namespace cellphys::scene {

namespace {

using json = nlohmann::json;
using ojson = nlohmann::ordered_json;

std::string join_error(const std::string& file, const std::string& path, const std::string& reason) {
  return path.empty() ? file + ": " + reason : file + ": " + path + ": " + reason;
}

const char* json_kind(const json& j) {
  switch (j.type()) {
    case json::value_t::null: return "null";
    case json::value_t::object: return "an object";
    case json::value_t::array: return "an array";
    case json::value_t::string: return "a string";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
    case json::value_t::number_float: return "a number";
    default: return "an unsupported value";
  }
}

std::string shown(const std::string& s) {
  // Keys and names from the file go into messages: keep them short and printable.
  std::string out = "'";
  for (size_t i = 0; i < s.size() && i < 64; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (s.size() > 64) out += "...";
  return out + "'";
}

std::string key_path(const std::string& base, const std::string& key) {
  return base.empty() ? key : base + "." + key;
}
std::string index_path(const std::string& base, size_t i) { return base + "[" + std::to_string(i) + "]"; }

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& reason) const {
    throw SceneError(file_, path, reason);
  }

  const json& object(const json& j, const std::string& path) const {
    if (!j.is_object()) fail(path, std::string("expected an object, got ") + json_kind(j));
    return j;
  }
  const json& array(const json& j, const std::string& path) const {
    if (!j.is_array()) fail(path, std::string("expected an array, got ") + json_kind(j));
    return j;
  }

  // Every key of `j` must be in `allowed`.
  void known_fields(const json& j, const std::string& path, const std::vector<std::string>& allowed,
                    const std::string& what) const {
    for (auto it = j.begin(); it != j.end(); ++it) {
      bool ok = false;
      for (const std::string& a : allowed) ok = ok || it.key() == a;
      if (!ok) {
        std::string list;
        for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(key_path(path, it.key()), std::string("unknown field ") + shown(it.key()) + " in " + what +
                                           " (known: " + list + ")");
      }
    }
  }

  const json* find(const json& j, const char* key) const {
    auto it = j.find(key);
    return it == j.end() ? nullptr : &*it;
  }
  const json& need(const json& j, const std::string& path, const char* key, const char* what) const {
    const json* v = find(j, key);
    if (!v) fail(path, std::string(what) + " needs the field '" + key + "'");
    return *v;
  }

  float number(const json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, std::string("expected a number, got ") + json_kind(j));
    const double d = j.get<double>();
    if (!std::isfinite(d)) fail(path, "number is not finite");
    const float f = static_cast<float>(d);
    if (!std::isfinite(f)) fail(path, "number does not fit a 32-bit float");
    return f;
  }
  float positive(const json& j, const std::string& path) const {
    const float f = number(j, path);
    if (!(f > 0.0f)) fail(path, "must be positive");
    return f;
  }
  float non_negative(const json& j, const std::string& path) const {
    const float f = number(j, path);
    if (!(f >= 0.0f)) fail(path, "must be >= 0");
    return f;
  }
  int64_t integer(const json& j, const std::string& path, int64_t lo, int64_t hi) const {
    if (!j.is_number_integer()) fail(path, std::string("expected an integer, got ") + json_kind(j));
    if (j.is_number_unsigned()) {
      const uint64_t u = j.get<uint64_t>();
      if (u > static_cast<uint64_t>(hi) || static_cast<int64_t>(u) < lo) fail(path, "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
      return static_cast<int64_t>(u);
    }
    const int64_t v = j.get<int64_t>();
    if (v < lo || v > hi) fail(path, "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    return v;
  }
  void vec(const json& j, const std::string& path, float* out, size_t n) const {
    array(j, path);
    if (j.size() != n) fail(path, "expected " + std::to_string(n) + " numbers, got " + std::to_string(j.size()));
    for (size_t i = 0; i < n; ++i) out[i] = number(j[i], index_path(path, i));
  }
  bool boolean(const json& j, const std::string& path) const {
    if (!j.is_boolean()) fail(path, std::string("expected true or false, got ") + json_kind(j));
    return j.get<bool>();
  }
  std::string string(const json& j, const std::string& path) const {
    if (!j.is_string()) fail(path, std::string("expected a string, got ") + json_kind(j));
    return j.get<std::string>();
  }
  std::string name(const json& j, const std::string& path) const {
    std::string s = string(j, path);
    if (s.empty()) fail(path, "must not be empty");
    return s;
  }
  // A body reference: string or integer, as text.
  std::string body_ref(const json& j, const std::string& path, bool* is_integer) const {
    if (j.is_number_integer()) {
      if (is_integer) *is_integer = true;
      return j.is_number_unsigned() ? std::to_string(j.get<uint64_t>()) : std::to_string(j.get<int64_t>());
    }
    if (j.is_string()) {
      if (is_integer) *is_integer = false;
      std::string s = j.get<std::string>();
      if (s.empty()) fail(path, "must not be empty");
      return s;
    }
    fail(path, std::string("expected a body id (a string or an integer), got ") + json_kind(j));
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

// Settings come from their table (runtime/ppe/settings.h): a setting's path is its place under
// "settings", its group the part before the last dot ("" at the top).
std::vector<std::string> keys_under(const std::string& group) {
  std::vector<std::string> keys;
  for (const ppe::Setting& row : ppe::settings_table()) {
    if (!group.empty() && row.path.rfind(group + ".", 0) != 0) continue;
    const std::string rest = group.empty() ? row.path : row.path.substr(group.size() + 1);
    const std::string key = rest.substr(0, rest.find('.'));
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
  }
  return keys;
}

void read_setting(const Reader& r, const json& j, const std::string& path, const ppe::Setting& row,
                  ppe::WorldSettings& s) {
  void* f = ppe::field_of(s, row);
  auto check = [&](double v, const std::string& where) {
    const std::string why = ppe::value_problem(row, v);
    if (!why.empty()) r.fail(where, why);
  };
  // The setting's own bounds first, so a bad value hears them rather than its C++ type's range.
  auto whole = [&](int64_t lo, int64_t hi) {
    const int64_t v = r.integer(j, path, std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max());
    check(double(v), path);
    if (v < lo || v > hi) r.fail(path, "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    return v;
  };
  switch (row.type) {
    case ppe::SettingType::f32:
      *static_cast<float*>(f) = r.number(j, path);
      check(*static_cast<float*>(f), path);
      break;
    case ppe::SettingType::vec3:
      r.vec(j, path, static_cast<float*>(f), 3);
      for (size_t k = 0; k < 3; ++k) check(static_cast<float*>(f)[k], index_path(path, k));
      break;
    case ppe::SettingType::u32:
      *static_cast<uint32_t*>(f) = static_cast<uint32_t>(whole(0, std::numeric_limits<uint32_t>::max()));
      break;
    case ppe::SettingType::i32:
      *static_cast<int*>(f) = static_cast<int>(whole(std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
      break;
    case ppe::SettingType::size:
      *static_cast<size_t*>(f) = static_cast<size_t>(whole(0, std::numeric_limits<int64_t>::max()));
      break;
    case ppe::SettingType::boolean: *static_cast<bool*>(f) = r.boolean(j, path); break;
    case ppe::SettingType::integrator: {
      const std::string n = r.string(j, path);
      if (!spu::parse_integrator(n, static_cast<spu::Integrator*>(f)))
        r.fail(path, "unknown integrator " + shown(n) + " (known: " + spu::integrator_names() + ")");
      break;
    }
    case ppe::SettingType::solver: {
      const std::string n = r.string(j, path);
      if (!spu::parse_solver(n, static_cast<spu::Solver*>(f)))
        r.fail(path, "unknown solver " + shown(n) + " (known: " + spu::solver_names() + ")");
      break;
    }
  }
}

// The object settings.<group> (settings itself for ""): every key a setting or a group of them.
void read_settings(const Reader& r, const json& j, const std::string& group, ppe::WorldSettings& s) {
  const std::string p = group.empty() ? "settings" : "settings." + group;
  r.object(j, p);
  const std::vector<std::string> keys = keys_under(group);
  r.known_fields(j, p, keys, p);
  for (const std::string& key : keys) {
    const json* v = r.find(j, key.c_str());
    if (!v) continue;
    const std::string path = key_path(group, key);
    if (const ppe::Setting* row = ppe::find_setting(path))
      read_setting(r, *v, "settings." + path, *row, s);
    else
      read_settings(r, *v, path, s);
  }
}



// The directory a scene's relative file names are read from: its own.
std::string directory_of(const std::string& scene_file) {
  const size_t slash = scene_file.find_last_of('/');
  return slash == std::string::npos ? std::string() : scene_file.substr(0, slash + 1);
}

void read_mesh(const Reader& r, const json& j, const std::string& p, const std::string& scene_file, ShapeSpec& s) {
  r.known_fields(j, p, {"name", "type", "vertices", "triangles", "obj"}, "a mesh");
  const json* obj = r.find(j, "obj");
  if (obj) {
    if (r.find(j, "vertices") || r.find(j, "triangles")) r.fail(p, "a mesh has either 'obj' or 'vertices' and 'triangles', not both");
    s.obj = r.name(*obj, p + ".obj");
    const std::string path = !s.obj.empty() && s.obj[0] == '/' ? s.obj : directory_of(scene_file) + s.obj;
    try {
      ObjMesh m = load_obj(path);
      s.vertices = std::move(m.vertices);
      s.triangles = std::move(m.triangles);
    } catch (const ObjError& e) {
      r.fail(p + ".obj", e.what());
    }
    return;
  }
  const std::string qv = p + ".vertices", qt = p + ".triangles";
  const json& vs = r.array(r.need(j, p, "vertices", "a mesh"), qv);
  s.vertices.resize(3 * vs.size());
  for (size_t i = 0; i < vs.size(); ++i) r.vec(vs[i], index_path(qv, i), &s.vertices[3 * i], 3);
  const json& ts = r.array(r.need(j, p, "triangles", "a mesh"), qt);
  s.triangles.resize(3 * ts.size());
  for (size_t i = 0; i < ts.size(); ++i) {
    const std::string q = index_path(qt, i);
    r.array(ts[i], q);
    if (ts[i].size() != 3) r.fail(q, "expected 3 vertex indices, got " + std::to_string(ts[i].size()));
    for (size_t c = 0; c < 3; ++c)
      s.triangles[3 * i + c] = static_cast<int32_t>(r.integer(ts[i][c], index_path(q, c), 0, int64_t(vs.size()) - 1));
  }
}

void read_height_field(const Reader& r, const json& j, const std::string& p, ShapeSpec& s) {
  r.known_fields(j, p, {"name", "type", "rows", "columns", "spacing", "heights"}, "a height field");
  s.rows = static_cast<int32_t>(r.integer(r.need(j, p, "rows", "a height field"), p + ".rows", 2, 1 << 22));
  s.columns = static_cast<int32_t>(r.integer(r.need(j, p, "columns", "a height field"), p + ".columns", 2, 1 << 22));
  r.vec(r.need(j, p, "spacing", "a height field"), p + ".spacing", s.spacing, 2);
  const std::string q = p + ".heights";
  const json& hs = r.array(r.need(j, p, "heights", "a height field"), q);
  const size_t want = size_t(s.rows) * size_t(s.columns);
  if (hs.size() != want)
    r.fail(q, std::to_string(hs.size()) + " heights, but rows x columns is " + std::to_string(want));
  s.heights.resize(want);
  for (size_t i = 0; i < want; ++i) s.heights[i] = r.number(hs[i], index_path(q, i));
}

void read_compound(const Reader& r, const json& j, const std::string& p, ShapeSpec& s) {
  r.known_fields(j, p, {"name", "type", "parts"}, "a compound");
  const std::string q = p + ".parts";
  const json& parts = r.array(r.need(j, p, "parts", "a compound"), q);
  if (parts.empty()) r.fail(q, "a compound needs at least one part");
  for (size_t i = 0; i < parts.size(); ++i) {
    const std::string pp = index_path(q, i);
    const json& pj = r.object(parts[i], pp);
    r.known_fields(pj, pp, {"shape", "position", "orientation", "scale"}, "a compound part");
    PartSpec part;
    part.shape = r.name(r.need(pj, pp, "shape", "a compound part"), pp + ".shape");
    if (const json* v = r.find(pj, "position")) r.vec(*v, pp + ".position", part.position, 3);
    if (const json* v = r.find(pj, "orientation")) r.vec(*v, pp + ".orientation", part.orientation, 4);
    if (const json* v = r.find(pj, "scale")) part.scale = r.positive(*v, pp + ".scale");
    s.parts.push_back(part);
  }
}

ShapeSpec read_shape(const Reader& r, const json& j, const std::string& p) {
  r.object(j, p);
  ShapeSpec s;
  s.name = r.name(r.need(j, p, "name", "a shape"), p + ".name");
  const std::string t = r.string(r.need(j, p, "type", "a shape"), p + ".type");
  if (!base::value_named(spu::kShapeTypeNames, t, &s.type))
    r.fail(p + ".type", "unknown shape type " + shown(t) + " (known: " + base::all_names(spu::kShapeTypeNames) + ")");
  switch (s.type) {
    case spu::ShapeType::sphere:
      r.known_fields(j, p, {"name", "type", "radius"}, "a sphere");
      s.radius = r.number(r.need(j, p, "radius", "a sphere"), p + ".radius");
      break;
    case spu::ShapeType::box:
      r.known_fields(j, p, {"name", "type", "half_extents"}, "a box");
      r.vec(r.need(j, p, "half_extents", "a box"), p + ".half_extents", s.half_extents, 3);
      break;
    case spu::ShapeType::capsule:
      r.known_fields(j, p, {"name", "type", "radius", "half_height"}, "a capsule");
      s.radius = r.number(r.need(j, p, "radius", "a capsule"), p + ".radius");
      s.half_height = r.number(r.need(j, p, "half_height", "a capsule"), p + ".half_height");
      break;
    case spu::ShapeType::hull: {
      r.known_fields(j, p, {"name", "type", "points"}, "a hull");
      const std::string q = p + ".points";
      const json& pts = r.array(r.need(j, p, "points", "a hull"), q);
      s.points.resize(3 * pts.size());
      for (size_t i = 0; i < pts.size(); ++i) r.vec(pts[i], index_path(q, i), &s.points[3 * i], 3);
      break;
    }
    case spu::ShapeType::plane:
      r.known_fields(j, p, {"name", "type", "normal", "offset"}, "a plane");
      r.vec(r.need(j, p, "normal", "a plane"), p + ".normal", s.normal, 3);
      if (const json* v = r.find(j, "offset")) s.offset = r.number(*v, p + ".offset");
      break;
    case spu::ShapeType::mesh: read_mesh(r, j, p, r.file(), s); break;
    case spu::ShapeType::height_field: read_height_field(r, j, p, s); break;
    case spu::ShapeType::compound: read_compound(r, j, p, s); break;
  }
  return s;
}

BodySpec read_body(const Reader& r, const json& j, const std::string& p, const std::set<std::string>& shapes) {
  r.object(j, p);
  r.known_fields(j, p,
                 {"id", "shape", "scale", "mass", "density", "inertia", "position", "orientation", "velocity",
                  "angular_velocity", "friction", "damping", "static", "sensor"},
                 "a body");
  BodySpec b;
  b.id = r.body_ref(r.need(j, p, "id", "a body"), p + ".id", &b.id_is_integer);
  if (!b.id_is_integer && b.id == kWorld) r.fail(p + ".id", "'world' is reserved for the world side of a force");
  b.shape = r.name(r.need(j, p, "shape", "a body"), p + ".shape");
  if (!shapes.count(b.shape)) r.fail(p + ".shape", "unknown shape " + shown(b.shape));
  if (const json* v = r.find(j, "static")) b.is_static = r.boolean(*v, p + ".static");
  if (const json* v = r.find(j, "sensor")) b.sensor = r.boolean(*v, p + ".sensor");
  if (const json* v = r.find(j, "scale")) b.scale = r.positive(*v, p + ".scale");
  const json* mass = r.find(j, "mass");
  const json* density = r.find(j, "density");
  if (mass && density) r.fail(p + ".density", "give mass or density, not both");
  if (mass) b.mass = r.positive(*mass, p + ".mass");
  if (density) b.density = r.positive(*density, p + ".density");
  if (const json* v = r.find(j, "inertia")) {
    b.has_inertia = true;
    r.vec(*v, p + ".inertia", b.inertia, 6);
  }
  if (const json* v = r.find(j, "position")) r.vec(*v, p + ".position", b.state.position, 3);
  if (const json* v = r.find(j, "orientation")) r.vec(*v, p + ".orientation", b.state.orientation, 4);
  if (const json* v = r.find(j, "velocity")) r.vec(*v, p + ".velocity", b.state.velocity, 3);
  if (const json* v = r.find(j, "angular_velocity")) r.vec(*v, p + ".angular_velocity", b.state.angular_velocity, 3);
  if (const json* v = r.find(j, "friction")) b.friction = r.non_negative(*v, p + ".friction");
  if (const json* v = r.find(j, "damping")) {
    const std::string q = p + ".damping";
    if (v->is_object()) {
      r.known_fields(*v, q, {"linear", "angular"}, "body damping");
      if (const json* w = r.find(*v, "linear")) b.linear_damping = r.non_negative(*w, q + ".linear");
      if (const json* w = r.find(*v, "angular")) b.angular_damping = r.non_negative(*w, q + ".angular");
    } else if (v->is_number()) {
      b.linear_damping = b.angular_damping = r.non_negative(*v, q);
    } else {
      r.fail(q, std::string("expected a number or {\"linear\", \"angular\"}, got ") + json_kind(*v));
    }
  }
  return b;
}

const gen::ForceInfo* force_info(const std::string& type) {
  for (const gen::ForceInfo& f : gen::kForceTable)
    if (type == f.name) return &f;
  return nullptr;
}

ForceSpec read_force(const Reader& r, const json& j, const std::string& p, const std::set<std::string>& bodies) {
  r.object(j, p);
  ForceSpec f;
  f.type = r.string(r.need(j, p, "type", "a force"), p + ".type");
  const gen::ForceInfo* info = force_info(f.type);
  if (!info) {
    std::string known;
    for (const gen::ForceInfo& k : gen::kForceTable)
      if (k.kind != gen::ForceKind::global) known += (known.empty() ? "" : ", ") + std::string(k.name);
    r.fail(p + ".type", "unknown force type " + shown(f.type) + " (known: " + known + ")");
  }
  if (info->kind == gen::ForceKind::global)
    r.fail(p + ".type", "force type '" + f.type + "' is global: it is set in the settings");
  f.a = r.body_ref(r.need(j, p, "a", "a force"), p + ".a", nullptr);
  if (!bodies.count(f.a)) r.fail(p + ".a", "no body with id " + shown(f.a));
  if (const json* v = r.find(j, "b")) {
    f.b = r.body_ref(*v, p + ".b", nullptr);
    if (f.b != kWorld && !bodies.count(f.b)) r.fail(p + ".b", "no body with id " + shown(f.b));
  }
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    if (k == "type" || k == "a" || k == "b") continue;
    const gen::ParamInfo* pi = nullptr;
    for (uint32_t i = 0; i < info->num_params; ++i)
      if (k == info->params[i].name) pi = &info->params[i];
    const std::string q = key_path(p, k);
    if (!pi) {
      std::string list = "type, a, b";
      for (uint32_t i = 0; i < info->num_params; ++i) list += ", " + std::string(info->params[i].name);
      r.fail(q, "unknown parameter " + shown(k) + " for force '" + f.type + "' (known: " + list + ")");
    }
    std::vector<float> values(pi->lanes);
    if (pi->type == gen::ParamType::vec3)
      r.vec(*it, q, values.data(), 3);
    else
      values[0] = r.number(*it, q);
    for (float v : values)
      if (!pi->admits(v)) r.fail(q, std::string("must be ") + pi->min_relation() + " " + std::to_string(pi->min));
    f.params.emplace_back(k, std::move(values));
  }
  return f;
}

// nlohmann keeps the last of duplicate keys silently; a scene file must not have any.
struct DuplicateKey {
  std::string key;
};

// Where the parser is, as a JSON path: kept from the parser's events so that a syntax error,
// an overflowing number or a duplicate key can be reported at its field.
class PathTracker {
 public:
  void object_start() { frames_.push_back({false, 0, {}, {}}); }
  void array_start() { frames_.push_back({true, 0, {}, {}}); }
  void end() {
    if (!frames_.empty()) frames_.pop_back();
    element_done();
  }
  void key(const std::string& k) {
    if (frames_.empty()) return;
    Frame& f = frames_.back();
    f.key = k;
    if (!f.keys.insert(k).second) throw DuplicateKey{k};
  }
  // A value finished: the next is the array's next element, or the object's next key.
  void element_done() {
    if (frames_.empty()) return;
    if (frames_.back().is_array)
      ++frames_.back().index;
    else
      frames_.back().key.clear();
  }
  std::string path() const {
    std::string p;
    for (const Frame& f : frames_) {
      if (f.is_array)
        p += "[" + std::to_string(f.index) + "]";
      else if (!f.key.empty())
        p += (p.empty() ? "" : ".") + f.key;
    }
    return p;
  }

 private:
  struct Frame {
    bool is_array;
    size_t index;
    std::string key;
    std::set<std::string> keys;
  };
  std::vector<Frame> frames_;
};

json parse_json(const std::string& text, const std::string& file) {
  PathTracker where;
  json::parser_callback_t cb = [&where](int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start: where.object_start(); break;
      case json::parse_event_t::array_start: where.array_start(); break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end: where.end(); break;
      case json::parse_event_t::key: where.key(parsed.get<std::string>()); break;
      case json::parse_event_t::value: where.element_done(); break;
    }
    return true;
  };
  auto strip = [](std::string what) {
    // "[json.exception.parse_error.101] parse error at line 1, column 2: ..." -> after "] "
    const size_t at = what.find("] ");
    return at == std::string::npos ? what : what.substr(at + 2);
  };
  try {
    return json::parse(text, cb, /*allow_exceptions=*/true, /*ignore_comments=*/false);
  } catch (const json::out_of_range& e) {  // 406: a number that overflows a double
    throw SceneError(file, where.path(), "number is not finite (" + strip(e.what()) + ")");
  } catch (const json::parse_error& e) {
    throw SceneError(file, where.path(), "not valid JSON: " + strip(e.what()));
  } catch (const DuplicateKey& d) {
    throw SceneError(file, where.path(), "duplicate key " + shown(d.key) + " (every key appears once per object)");
  } catch (const json::exception& e) {
    throw SceneError(file, where.path(), "not valid JSON: " + strip(e.what()));
  }
}

// ---- writing ----

// A float as the double whose shortest decimal form is the float's shortest form, when that
// double still reads back (through float) to the same float; the float itself otherwise.
double tidy(float f) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf - 1, f);
  if (res.ec != std::errc()) return f;
  *res.ptr = 0;
  const double d = std::strtod(buf, nullptr);
  return static_cast<float>(d) == f ? d : static_cast<double>(f);
}
ojson arr(const float* v, size_t n) {
  ojson a = ojson::array();
  for (size_t i = 0; i < n; ++i) a.push_back(tidy(v[i]));
  return a;
}

ojson setting_json(const ppe::WorldSettings& s, const ppe::Setting& row) {
  const void* f = ppe::field_of(s, row);
  switch (row.type) {
    case ppe::SettingType::f32: return tidy(*static_cast<const float*>(f));
    case ppe::SettingType::vec3: return arr(static_cast<const float*>(f), 3);
    case ppe::SettingType::u32: return *static_cast<const uint32_t*>(f);
    case ppe::SettingType::i32: return *static_cast<const int*>(f);
    case ppe::SettingType::size: return *static_cast<const size_t*>(f);
    case ppe::SettingType::boolean: return *static_cast<const bool*>(f);
    case ppe::SettingType::integrator: return spu::integrator_name(*static_cast<const spu::Integrator*>(f));
    case ppe::SettingType::solver: return spu::solver_name(*static_cast<const spu::Solver*>(f));
  }
  return nullptr;
}

}  // namespace

SceneError::SceneError(std::string file, std::string path, std::string reason)
    : std::runtime_error(join_error(file, path, reason)),
      file_(std::move(file)),
      path_(std::move(path)),
      reason_(std::move(reason)) {}

SceneDesc parse_scene(const std::string& text, const std::string& name) {
  const Reader r(name);
  const json root = parse_json(text, name);
  r.object(root, "");
  r.known_fields(root, "", {"description", "settings", "shapes", "bodies", "forces"}, "a scene");
  SceneDesc scene;
  scene.source = name;
  if (const json* v = r.find(root, "description")) scene.description = r.string(*v, "description");
  if (const json* v = r.find(root, "settings")) read_settings(r, *v, "", scene.settings);

  std::set<std::string> shape_names;
  if (const json* v = r.find(root, "shapes")) {
    r.array(*v, "shapes");
    for (size_t i = 0; i < v->size(); ++i) {
      const std::string p = index_path("shapes", i);
      scene.shapes.push_back(read_shape(r, (*v)[i], p));
      if (!shape_names.insert(scene.shapes.back().name).second)
        r.fail(p + ".name", "a shape named " + shown(scene.shapes.back().name) + " already exists");
    }
  }
  std::set<std::string> body_ids;
  if (const json* v = r.find(root, "bodies")) {
    r.array(*v, "bodies");
    for (size_t i = 0; i < v->size(); ++i) {
      const std::string p = index_path("bodies", i);
      BodySpec b = read_body(r, (*v)[i], p, shape_names);
      const ShapeSpec* shape = nullptr;
      for (const ShapeSpec& s : scene.shapes)
        if (s.name == b.shape) shape = &s;
      const bool is_static = b.is_static || shape->type == spu::ShapeType::plane || spu::is_triangle_surface(shape->type);
      if (!is_static && b.mass == 0.0f && b.density == 0.0f) r.fail(p, "a dynamic body needs a mass or a density");
      if (!body_ids.insert(b.id).second) r.fail(p + ".id", "a body with id " + shown(b.id) + " already exists");
      scene.bodies.push_back(std::move(b));
    }
  }
  if (const json* v = r.find(root, "forces")) {
    r.array(*v, "forces");
    for (size_t i = 0; i < v->size(); ++i) scene.forces.push_back(read_force(r, (*v)[i], index_path("forces", i), body_ids));
  }
  return scene;
}

SceneDesc load_scene(const std::string& path) {
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path, "", std::string("cannot open: ") + (errno ? std::strerror(errno) : "unknown error"));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  constexpr std::streamoff kMaxBytes = std::streamoff(1) << 30;
  if (size < 0) throw SceneError(path, "", "cannot read (not a regular file?)");
  if (size > kMaxBytes) throw SceneError(path, "", "file is larger than 1 GiB");
  in.seekg(0, std::ios::beg);
  std::string text(static_cast<size_t>(size), '\0');
  if (size > 0 && !in.read(&text[0], size)) throw SceneError(path, "", "read error");
  return parse_scene(text, path);
}

std::string write_scene(const SceneDesc& scene) {
  const ppe::WorldSettings& s = scene.settings;
  ojson root = ojson::object();
  root["description"] = scene.description;
  ojson st = ojson::object();
  for (const ppe::Setting& row : ppe::settings_table()) {
    ojson* at = &st;
    std::string rest = row.path;
    for (size_t dot; (dot = rest.find('.')) != std::string::npos; rest = rest.substr(dot + 1))
      at = &(*at)[rest.substr(0, dot)];
    (*at)[rest] = setting_json(s, row);
  }
  root["settings"] = st;

  ojson shapes = ojson::array();
  for (const ShapeSpec& sh : scene.shapes) {
    ojson o = ojson::object();
    o["name"] = sh.name;
    o["type"] = spu::shape_type_name(sh.type);
    switch (sh.type) {
      case spu::ShapeType::sphere: o["radius"] = tidy(sh.radius); break;
      case spu::ShapeType::box: o["half_extents"] = arr(sh.half_extents, 3); break;
      case spu::ShapeType::capsule:
        o["radius"] = tidy(sh.radius);
        o["half_height"] = tidy(sh.half_height);
        break;
      case spu::ShapeType::hull: {
        ojson pts = ojson::array();
        for (size_t i = 0; i + 2 < sh.points.size(); i += 3) pts.push_back(arr(&sh.points[i], 3));
        o["points"] = pts;
        break;
      }
      case spu::ShapeType::plane:
        o["normal"] = arr(sh.normal, 3);
        o["offset"] = tidy(sh.offset);
        break;
      case spu::ShapeType::mesh: {  // inline, whatever it was read from: the written file stands alone
        ojson vs = ojson::array(), ts = ojson::array();
        for (size_t i = 0; i + 2 < sh.vertices.size(); i += 3) vs.push_back(arr(&sh.vertices[i], 3));
        for (size_t i = 0; i + 2 < sh.triangles.size(); i += 3)
          ts.push_back(ojson::array({sh.triangles[i], sh.triangles[i + 1], sh.triangles[i + 2]}));
        o["vertices"] = vs;
        o["triangles"] = ts;
        break;
      }
      case spu::ShapeType::compound: {
        ojson parts = ojson::array();
        for (const PartSpec& part : sh.parts) {
          ojson po = ojson::object();
          po["shape"] = part.shape;
          po["position"] = arr(part.position, 3);
          po["orientation"] = arr(part.orientation, 4);
          po["scale"] = tidy(part.scale);
          parts.push_back(po);
        }
        o["parts"] = parts;
        break;
      }
      case spu::ShapeType::height_field: {
        o["rows"] = sh.rows;
        o["columns"] = sh.columns;
        o["spacing"] = arr(sh.spacing, 2);
        ojson hs = ojson::array();
        for (float h : sh.heights) hs.push_back(tidy(h));
        o["heights"] = hs;
        break;
      }
    }
    shapes.push_back(o);
  }
  root["shapes"] = shapes;

  ojson bodies = ojson::array();
  for (const BodySpec& b : scene.bodies) {
    ojson o = ojson::object();
    if (b.id_is_integer) {
      // kept as text; an integer id always came from an integer
      if (!b.id.empty() && b.id[0] == '-')
        o["id"] = std::strtoll(b.id.c_str(), nullptr, 10);
      else
        o["id"] = std::strtoull(b.id.c_str(), nullptr, 10);
    } else {
      o["id"] = b.id;
    }
    o["shape"] = b.shape;
    if (b.is_static) o["static"] = true;
    if (b.sensor) o["sensor"] = true;
    if (b.scale != 1.0f) o["scale"] = tidy(b.scale);
    if (b.mass != 0.0f) o["mass"] = tidy(b.mass);
    if (b.density != 0.0f) o["density"] = tidy(b.density);
    if (b.has_inertia) o["inertia"] = arr(b.inertia, 6);
    o["position"] = arr(b.state.position, 3);
    o["orientation"] = arr(b.state.orientation, 4);
    o["velocity"] = arr(b.state.velocity, 3);
    o["angular_velocity"] = arr(b.state.angular_velocity, 3);
    o["friction"] = tidy(b.friction);
    if (b.linear_damping == b.angular_damping)
      o["damping"] = tidy(b.linear_damping);
    else
      o["damping"] = {{"linear", tidy(b.linear_damping)}, {"angular", tidy(b.angular_damping)}};
    bodies.push_back(o);
  }
  root["bodies"] = bodies;

  ojson forces = ojson::array();
  for (const ForceSpec& f : scene.forces) {
    ojson o = ojson::object();
    o["type"] = f.type;
    auto ref = [&scene](const std::string& id) -> ojson {
      for (const BodySpec& b : scene.bodies)
        if (b.id == id && b.id_is_integer) {
          if (!id.empty() && id[0] == '-') return std::strtoll(id.c_str(), nullptr, 10);
          return std::strtoull(id.c_str(), nullptr, 10);
        }
      return id;
    };
    o["a"] = ref(f.a);
    o["b"] = f.b == kWorld ? ojson(kWorld) : ref(f.b);
    for (const auto& [name, values] : f.params)
      o[name] = values.size() == 1 ? ojson(tidy(values[0])) : arr(values.data(), values.size());
    forces.push_back(o);
  }
  root["forces"] = forces;
  return root.dump(2) + "\n";
}

// ---- equality ----

namespace {
template <class T>
const T* as(const void* field) {
  return static_cast<const T*>(field);
}

template <size_t N>
bool same(const float (&a)[N], const float (&b)[N]) {
  for (size_t i = 0; i < N; ++i)
    if (!(a[i] == b[i])) return false;
  return true;
}
bool same(const ppe::BodyState& a, const ppe::BodyState& b) {
  return same(a.position, b.position) && same(a.orientation, b.orientation) && same(a.velocity, b.velocity) &&
         same(a.angular_velocity, b.angular_velocity);
}
}  // namespace

bool operator==(const ppe::WorldSettings& a, const ppe::WorldSettings& b) {
  for (const ppe::Setting& row : ppe::settings_table()) {
    const void *x = ppe::field_of(a, row), *y = ppe::field_of(b, row);
    const size_t lanes = row.type == ppe::SettingType::vec3 ? 3 : 1;
    bool same_value = true;
    switch (row.type) {
      case ppe::SettingType::f32:
      case ppe::SettingType::vec3:  // as numbers: 0 equals -0, NaN nothing
        for (size_t k = 0; k < lanes; ++k) same_value = same_value && as<float>(x)[k] == as<float>(y)[k];
        break;
      case ppe::SettingType::u32: same_value = *as<uint32_t>(x) == *as<uint32_t>(y); break;
      case ppe::SettingType::i32: same_value = *as<int>(x) == *as<int>(y); break;
      case ppe::SettingType::size: same_value = *as<size_t>(x) == *as<size_t>(y); break;
      case ppe::SettingType::boolean: same_value = *as<bool>(x) == *as<bool>(y); break;
      case ppe::SettingType::integrator: same_value = *as<spu::Integrator>(x) == *as<spu::Integrator>(y); break;
      case ppe::SettingType::solver: same_value = *as<spu::Solver>(x) == *as<spu::Solver>(y); break;
    }
    if (!same_value) return false;
  }
  return true;
}

bool operator==(const ShapeSpec& a, const ShapeSpec& b) {
  if (a.name != b.name || a.type != b.type) return false;
  switch (a.type) {
    case spu::ShapeType::sphere: return a.radius == b.radius;
    case spu::ShapeType::box: return same(a.half_extents, b.half_extents);
    case spu::ShapeType::capsule: return a.radius == b.radius && a.half_height == b.half_height;
    case spu::ShapeType::hull: return a.points == b.points;
    case spu::ShapeType::plane: return same(a.normal, b.normal) && a.offset == b.offset;
    case spu::ShapeType::mesh: return a.vertices == b.vertices && a.triangles == b.triangles;  // not where it was read from
    case spu::ShapeType::height_field:
      return a.rows == b.rows && a.columns == b.columns && a.spacing[0] == b.spacing[0] && a.spacing[1] == b.spacing[1] &&
             a.heights == b.heights;
    case spu::ShapeType::compound: return a.parts == b.parts;
  }
  return false;
}

bool PartSpec::operator==(const PartSpec& o) const {
  return shape == o.shape && std::equal(position, position + 3, o.position) &&
         std::equal(orientation, orientation + 4, o.orientation) && scale == o.scale;
}

bool operator==(const BodySpec& a, const BodySpec& b) {
  return a.id == b.id && a.id_is_integer == b.id_is_integer && a.shape == b.shape && a.scale == b.scale &&
         a.mass == b.mass && a.density == b.density && a.has_inertia == b.has_inertia &&
         (!a.has_inertia || same(a.inertia, b.inertia)) && same(a.state, b.state) && a.friction == b.friction &&
         a.linear_damping == b.linear_damping && a.angular_damping == b.angular_damping && a.is_static == b.is_static &&
         a.sensor == b.sensor;
}

bool operator==(const ForceSpec& a, const ForceSpec& b) {
  return a.type == b.type && a.a == b.a && a.b == b.b && a.params == b.params;
}

bool operator==(const SceneDesc& a, const SceneDesc& b) {
  return a.description == b.description && a.settings == b.settings && a.shapes == b.shapes &&
         a.bodies == b.bodies && a.forces == b.forces;
}

}  // namespace cellphys::scene
