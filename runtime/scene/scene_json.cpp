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
#include "runtime/ppe/settings.h"
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

// The forces' globals sit in settings by their generated places ("gravity", "contact.slop"):
// the group of a place is the part before its last dot ("" at the top).
std::string group_of(const std::string& setting) {
  const size_t dot = setting.rfind('.');
  return dot == std::string::npos ? "" : setting.substr(0, dot);
}

// The keys directly under `group` that the forces' globals take, with `hand` (the other
// settings there) first.
std::vector<std::string> global_keys(const std::string& group, std::vector<std::string> hand) {
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const std::string setting = gen::kGlobalTable[i].setting;
    if (!group.empty() && setting.rfind(group + ".", 0) != 0) continue;
    const std::string rest = group.empty() ? setting : setting.substr(group.size() + 1);
    const std::string key = rest.substr(0, rest.find('.'));
    if (std::find(hand.begin(), hand.end(), key) == hand.end()) hand.push_back(key);
  }
  return hand;
}

// Reads the globals whose place is directly under `group` from j (the object at `path`).
void read_globals(const Reader& r, const json& j, const std::string& group, const std::string& path,
                  ppe::WorldSettings& s) {
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const gen::GlobalInfo& g = gen::kGlobalTable[i];
    const std::string setting = g.setting;
    if (group_of(setting) != group) continue;
    const std::string key = group.empty() ? setting : setting.substr(group.size() + 1);
    const json* v = r.find(j, key.c_str());
    if (!v) continue;
    const std::string q = key_path(path, key);
    float* lanes = ppe::global_lanes(s.globals, g);
    if (g.param.lanes == 1)
      lanes[0] = r.number(*v, q);
    else
      r.vec(*v, q, lanes, g.param.lanes);
    for (uint32_t l = 0; l < g.param.lanes; ++l) {
      const std::string why = ppe::global_problem(g, lanes[l]);
      if (!why.empty()) r.fail(g.param.lanes == 1 ? q : index_path(q, l), why);
    }
  }
}

bool is_global(const std::string& setting) {
  for (int i = 0; i < gen::kNumGlobals; ++i)
    if (setting == gen::kGlobalTable[i].setting) return true;
  return false;
}

// settings.<group>: its globals and the other settings there (`hand`, read by the caller).
void read_global_group(const Reader& r, const json& j, const std::string& group, std::vector<std::string> hand,
                       ppe::WorldSettings& s) {
  const std::string q = "settings." + group;
  r.object(j, q);
  r.known_fields(j, q, global_keys(group, std::move(hand)), q);
  read_globals(r, j, group, q, s);
}

void read_settings(const Reader& r, const json& j, ppe::WorldSettings& s) {
  const std::string p = "settings";
  r.object(j, p);
  const std::vector<std::string> hand = {"dt", "integrator", "solver", "tolerance", "max_halvings", "sleeping",
                                         "sleep", "workers", "contact", "local_store_bytes", "decouple", "region"};
  const std::vector<std::string> top = global_keys("", hand);
  r.known_fields(j, p, top, "settings");
  read_globals(r, j, "", p, s);
  for (const std::string& key : top) {  // a group of globals alone (a force's with no other settings)
    const json* v = r.find(j, key.c_str());
    if (v && std::find(hand.begin(), hand.end(), key) == hand.end() && !is_global(key)) read_global_group(r, *v, key, {}, s);
  }
  if (const json* v = r.find(j, "dt")) s.dt = r.positive(*v, "settings.dt");
  if (const json* v = r.find(j, "integrator")) {
    const std::string n = r.string(*v, "settings.integrator");
    if (!spu::parse_integrator(n, &s.integrator))
      r.fail("settings.integrator",
             "unknown integrator " + shown(n) +
                 " (known: implicit_split, implicit_euler, rosenbrock, symplectic_euler, explicit_euler, rk4)");
  }
  if (const json* v = r.find(j, "solver")) {
    const std::string n = r.string(*v, "settings.solver");
    if (!parse_solver(n, &s.solver)) r.fail("settings.solver", "unknown solver " + shown(n) + " (known: cgs, bicgstab, direct)");
  }
  if (const json* v = r.find(j, "tolerance")) s.tolerance = r.positive(*v, "settings.tolerance");
  if (const json* v = r.find(j, "max_halvings"))
    s.max_halvings = static_cast<uint32_t>(r.integer(*v, "settings.max_halvings", 0, 16));
  if (const json* v = r.find(j, "sleeping")) s.sleeping = r.boolean(*v, "settings.sleeping");
  if (const json* v = r.find(j, "sleep")) {
    const std::string q = "settings.sleep";
    r.object(*v, q);
    r.known_fields(*v, q, {"linear", "angular", "time"}, "settings.sleep");
    if (const json* w = r.find(*v, "linear")) s.sleep_linear = r.non_negative(*w, q + ".linear");
    if (const json* w = r.find(*v, "angular")) s.sleep_angular = r.non_negative(*w, q + ".angular");
    if (const json* w = r.find(*v, "time")) s.sleep_time = r.non_negative(*w, q + ".time");
  }
  if (const json* v = r.find(j, "workers")) s.workers = static_cast<int>(r.integer(*v, "settings.workers", 1, 256));
  if (const json* v = r.find(j, "contact")) {
    read_global_group(r, *v, "contact", {"margin"}, s);
    if (const json* w = r.find(*v, "margin")) s.contact_margin = r.non_negative(*w, "settings.contact.margin");
  }
  if (const json* v = r.find(j, "local_store_bytes"))
    s.local_store_bytes = static_cast<size_t>(r.integer(*v, "settings.local_store_bytes", 16 * 1024, int64_t(1) << 32));
  if (const json* v = r.find(j, "decouple")) {
    const std::string q = "settings.decouple";
    r.object(*v, q);
    r.known_fields(*v, q, {"sweeps", "tolerance"}, "settings.decouple");
    if (const json* w = r.find(*v, "sweeps")) s.decouple_sweeps = static_cast<uint32_t>(r.integer(*w, q + ".sweeps", 1, 64));
    if (const json* w = r.find(*v, "tolerance")) s.decouple_tolerance = r.non_negative(*w, q + ".tolerance");
  }
  if (const json* v = r.find(j, "region")) {
    const std::string q = "settings.region";
    r.object(*v, q);
    r.known_fields(*v, q, {"min", "max"}, "settings.region");
    if (const json* w = r.find(*v, "min")) r.vec(*w, q + ".min", s.region_min, 3);
    if (const json* w = r.find(*v, "max")) r.vec(*w, q + ".max", s.region_max, 3);
  }
}

ShapeSpec read_shape(const Reader& r, const json& j, const std::string& p) {
  r.object(j, p);
  ShapeSpec s;
  s.name = r.name(r.need(j, p, "name", "a shape"), p + ".name");
  const std::string t = r.string(r.need(j, p, "type", "a shape"), p + ".type");
  if (t == "sphere") {
    s.type = ShapeType::sphere;
    r.known_fields(j, p, {"name", "type", "radius"}, "a sphere");
    s.radius = r.number(r.need(j, p, "radius", "a sphere"), p + ".radius");
  } else if (t == "box") {
    s.type = ShapeType::box;
    r.known_fields(j, p, {"name", "type", "half_extents"}, "a box");
    r.vec(r.need(j, p, "half_extents", "a box"), p + ".half_extents", s.half_extents, 3);
  } else if (t == "capsule") {
    s.type = ShapeType::capsule;
    r.known_fields(j, p, {"name", "type", "radius", "half_height"}, "a capsule");
    s.radius = r.number(r.need(j, p, "radius", "a capsule"), p + ".radius");
    s.half_height = r.number(r.need(j, p, "half_height", "a capsule"), p + ".half_height");
  } else if (t == "hull") {
    s.type = ShapeType::hull;
    r.known_fields(j, p, {"name", "type", "points"}, "a hull");
    const std::string q = p + ".points";
    const json& pts = r.array(r.need(j, p, "points", "a hull"), q);
    s.points.resize(3 * pts.size());
    for (size_t i = 0; i < pts.size(); ++i) r.vec(pts[i], index_path(q, i), &s.points[3 * i], 3);
  } else if (t == "plane") {
    s.type = ShapeType::plane;
    r.known_fields(j, p, {"name", "type", "normal", "offset"}, "a plane");
    r.vec(r.need(j, p, "normal", "a plane"), p + ".normal", s.normal, 3);
    if (const json* v = r.find(j, "offset")) s.offset = r.number(*v, p + ".offset");
  } else {
    r.fail(p + ".type", "unknown shape type " + shown(t) + " (known: sphere, box, capsule, hull, plane)");
  }
  return s;
}

BodySpec read_body(const Reader& r, const json& j, const std::string& p, const std::set<std::string>& shapes) {
  r.object(j, p);
  r.known_fields(j, p,
                 {"id", "shape", "scale", "mass", "density", "inertia", "position", "orientation", "velocity",
                  "angular_velocity", "friction", "damping", "static"},
                 "a body");
  BodySpec b;
  b.id = r.body_ref(r.need(j, p, "id", "a body"), p + ".id", &b.id_is_integer);
  if (!b.id_is_integer && b.id == kWorld) r.fail(p + ".id", "'world' is reserved for the world side of a force");
  b.shape = r.name(r.need(j, p, "shape", "a body"), p + ".shape");
  if (!shapes.count(b.shape)) r.fail(p + ".shape", "unknown shape " + shown(b.shape));
  if (const json* v = r.find(j, "static")) b.is_static = r.boolean(*v, p + ".static");
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
  if (const json* v = r.find(j, "position")) r.vec(*v, p + ".position", b.position, 3);
  if (const json* v = r.find(j, "orientation")) r.vec(*v, p + ".orientation", b.orientation, 4);
  if (const json* v = r.find(j, "velocity")) r.vec(*v, p + ".velocity", b.velocity, 3);
  if (const json* v = r.find(j, "angular_velocity")) r.vec(*v, p + ".angular_velocity", b.angular_velocity, 3);
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

}  // namespace

SceneError::SceneError(std::string file, std::string path, std::string reason)
    : std::runtime_error(join_error(file, path, reason)),
      file_(std::move(file)),
      path_(std::move(path)),
      reason_(std::move(reason)) {}

const char* shape_type_name(ShapeType t) {
  switch (t) {
    case ShapeType::sphere: return "sphere";
    case ShapeType::box: return "box";
    case ShapeType::capsule: return "capsule";
    case ShapeType::hull: return "hull";
    case ShapeType::plane: return "plane";
  }
  return "?";
}

bool parse_solver(const std::string& name, spu::Solver* out) {
  if (name == "cgs") *out = spu::Solver::cgs;
  else if (name == "bicgstab") *out = spu::Solver::bicgstab;
  else if (name == "direct") *out = spu::Solver::direct;
  else return false;
  return true;
}

const char* solver_name(spu::Solver s) {
  switch (s) {
    case spu::Solver::cgs: return "cgs";
    case spu::Solver::bicgstab: return "bicgstab";
    case spu::Solver::direct: return "direct";
  }
  return "?";
}

SceneDesc parse_scene(const std::string& text, const std::string& name) {
  const Reader r(name);
  const json root = parse_json(text, name);
  r.object(root, "");
  r.known_fields(root, "", {"description", "settings", "shapes", "bodies", "forces"}, "a scene");
  SceneDesc scene;
  scene.source = name;
  if (const json* v = r.find(root, "description")) scene.description = r.string(*v, "description");
  if (const json* v = r.find(root, "settings")) read_settings(r, *v, scene.settings);

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
      const bool is_static = b.is_static || shape->type == ShapeType::plane;
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
  st["dt"] = tidy(s.dt);
  st["integrator"] = spu::integrator_name(s.integrator);
  st["solver"] = solver_name(s.solver);
  st["tolerance"] = tidy(s.tolerance);
  st["max_halvings"] = s.max_halvings;
  st["sleeping"] = s.sleeping;
  st["sleep"] = {{"linear", tidy(s.sleep_linear)}, {"angular", tidy(s.sleep_angular)}, {"time", tidy(s.sleep_time)}};
  st["workers"] = s.workers;
  st["contact"] = {{"margin", tidy(s.contact_margin)}};
  st["local_store_bytes"] = s.local_store_bytes;
  st["decouple"] = {{"sweeps", s.decouple_sweeps}, {"tolerance", tidy(s.decouple_tolerance)}};
  st["region"] = {{"min", arr(s.region_min, 3)}, {"max", arr(s.region_max, 3)}};
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const gen::GlobalInfo& g = gen::kGlobalTable[i];
    const std::string setting = g.setting, group = group_of(setting);
    const float* lanes = ppe::global_lanes(s.globals, g);
    ojson& at = group.empty() ? st : st[group];
    at[group.empty() ? setting : setting.substr(group.size() + 1)] = g.param.lanes == 1 ? ojson(tidy(lanes[0])) : arr(lanes, g.param.lanes);
  }
  root["settings"] = st;

  ojson shapes = ojson::array();
  for (const ShapeSpec& sh : scene.shapes) {
    ojson o = ojson::object();
    o["name"] = sh.name;
    o["type"] = shape_type_name(sh.type);
    switch (sh.type) {
      case ShapeType::sphere: o["radius"] = tidy(sh.radius); break;
      case ShapeType::box: o["half_extents"] = arr(sh.half_extents, 3); break;
      case ShapeType::capsule:
        o["radius"] = tidy(sh.radius);
        o["half_height"] = tidy(sh.half_height);
        break;
      case ShapeType::hull: {
        ojson pts = ojson::array();
        for (size_t i = 0; i + 2 < sh.points.size(); i += 3) pts.push_back(arr(&sh.points[i], 3));
        o["points"] = pts;
        break;
      }
      case ShapeType::plane:
        o["normal"] = arr(sh.normal, 3);
        o["offset"] = tidy(sh.offset);
        break;
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
    if (b.scale != 1.0f) o["scale"] = tidy(b.scale);
    if (b.mass != 0.0f) o["mass"] = tidy(b.mass);
    if (b.density != 0.0f) o["density"] = tidy(b.density);
    if (b.has_inertia) o["inertia"] = arr(b.inertia, 6);
    o["position"] = arr(b.position, 3);
    o["orientation"] = arr(b.orientation, 4);
    o["velocity"] = arr(b.velocity, 3);
    o["angular_velocity"] = arr(b.angular_velocity, 3);
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
template <size_t N>
bool same(const float (&a)[N], const float (&b)[N]) {
  for (size_t i = 0; i < N; ++i)
    if (!(a[i] == b[i])) return false;
  return true;
}
}  // namespace

bool operator==(const ppe::WorldSettings& a, const ppe::WorldSettings& b) {
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const gen::GlobalInfo& g = gen::kGlobalTable[i];
    const float *x = ppe::global_lanes(a.globals, g), *y = ppe::global_lanes(b.globals, g);
    for (uint32_t l = 0; l < g.param.lanes; ++l)
      if (!(x[l] == y[l])) return false;
  }
  return a.dt == b.dt && a.integrator == b.integrator && a.solver == b.solver &&
         a.tolerance == b.tolerance && a.max_halvings == b.max_halvings && a.sleeping == b.sleeping &&
         a.workers == b.workers && a.contact_margin == b.contact_margin && a.local_store_bytes == b.local_store_bytes &&
         a.decouple_sweeps == b.decouple_sweeps && a.decouple_tolerance == b.decouple_tolerance &&
         same(a.region_min, b.region_min) && same(a.region_max, b.region_max) && a.sleep_linear == b.sleep_linear &&
         a.sleep_angular == b.sleep_angular && a.sleep_time == b.sleep_time;
}

bool operator==(const ShapeSpec& a, const ShapeSpec& b) {
  if (a.name != b.name || a.type != b.type) return false;
  switch (a.type) {
    case ShapeType::sphere: return a.radius == b.radius;
    case ShapeType::box: return same(a.half_extents, b.half_extents);
    case ShapeType::capsule: return a.radius == b.radius && a.half_height == b.half_height;
    case ShapeType::hull: return a.points == b.points;
    case ShapeType::plane: return same(a.normal, b.normal) && a.offset == b.offset;
  }
  return false;
}

bool operator==(const BodySpec& a, const BodySpec& b) {
  return a.id == b.id && a.id_is_integer == b.id_is_integer && a.shape == b.shape && a.scale == b.scale &&
         a.mass == b.mass && a.density == b.density && a.has_inertia == b.has_inertia &&
         (!a.has_inertia || same(a.inertia, b.inertia)) && same(a.position, b.position) &&
         same(a.orientation, b.orientation) && same(a.velocity, b.velocity) &&
         same(a.angular_velocity, b.angular_velocity) && a.friction == b.friction &&
         a.linear_damping == b.linear_damping && a.angular_damping == b.angular_damping && a.is_static == b.is_static;
}

bool operator==(const ForceSpec& a, const ForceSpec& b) {
  return a.type == b.type && a.a == b.a && a.b == b.b && a.params == b.params;
}

bool operator==(const SceneDesc& a, const SceneDesc& b) {
  return a.description == b.description && a.settings == b.settings && a.shapes == b.shapes &&
         a.bodies == b.bodies && a.forces == b.forces;
}

}  // namespace cellphys::scene
