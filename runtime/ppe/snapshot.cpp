// World snapshots: the whole world as bytes, and back. Layout (little-endian, every float by
// its bits):
//   header  "CELLSNAP" | u32 version | u32 header bytes (32) | u64 payload bytes |
//           u32 checksum of the payload (spu::checksum) | u32 zero
//   payload settings | step counter | shapes | bodies | forces | sleeping groups | free groups |
//           contact memory (pairs in key order: key, sliding, slip, version 10 on: drift[3],
//           held gaps, then anchors; before version 10 a pair restores with no drift and no
//           held gaps, so its first step decides as a world without them did) |
//           event memory (touching pairs, sensor overlaps: u32 count + sorted u64 keys each;
//           version 5 on: a version-4 snapshot restores with none, so its first step reports
//           the touches it has as begun)
//   shapes:  version 6 on may hold meshes and height fields, stored as they were given (the
//           vertices and triangles, or the grid) and rebuilt by the dictionary, which builds
//           the same surface from the same input; and compounds, their parts as stored
//           (shape index, position, orientation, scale: already centred)
//   settings: u32 count, then per setting (runtime/ppe/settings.h) its scene path and its value
//           (f32 4 bytes, vec3 12, u32 and i32 4, size 8, boolean 1, integrator and solver u32),
//           each as u32 length + bytes: matched by name, so a build with other forces refuses
//           a setting it lacks, or lacks one it has, by name; before version 7 there was no
//           whole_island_bytes, and such a world restores with 0 (big islands split, as then);
//           before version 9 no contact.joined_hold_depth, and such a world restores with
//           contact.hold_depth's value, its sleeping contacts held at it (every contact's spring as
//           then; a gap between two bodies joints join is no longer taken to close by gravity's
//           fall, docs/joints.md)
//   sleeping contact: u32 a, b | f32 point[3], normal[3] | f32 penetration, friction, mass, load |
//           f32 anchor[3] | f32 sticking | version 9 on: f32 hold, fall
//   body (136 bytes): u8 alive, static, awake, flags (1: sensor; version 4: 0) | u32 shape | f32 scale, mass | f32 inertia[6],
//           inverse inertia[6] | position[3], orientation[4], velocity[3], angular velocity[3] |
//           f32 friction, linear and angular damping, sleep timer | i32 sleeping group
// Every record is checked before the world is returned (runtime/ppe/snapshot_checks.h); a
// refusal throws, and the new world is dropped with it.
// A restored world steps on bit for bit: everything a step reads across steps is here (the
// broad phase's kept sort order only speeds it up; its pairs come out sorted).
#include <algorithm>
#include <cstring>
#include <string>
#include <type_traits>

#include "runtime/ppe/contact_loads.h"
#include "runtime/ppe/settings.h"
#include "runtime/ppe/snapshot_checks.h"
#include "runtime/ppe/world_impl.h"

namespace cellphys::ppe {

namespace {

constexpr char kMagic[8] = {'C', 'E', 'L', 'L', 'S', 'N', 'A', 'P'};
constexpr uint32_t kVersion = 10;
constexpr uint32_t kOldestVersion = 4;  // without the event memory
constexpr size_t kHeaderBytes = 32;
// The fewest bytes of each record, so that a count the rest of the file cannot hold is refused
// before anything is allocated for it.
constexpr size_t kBodyBytes = 4 + 4 + 4 + 4 + 4 * 6 + 4 * 6 + 4 * 13 + 4 * 4 + 4;
constexpr size_t kContactBytes = 4 + 4 + 4 * 3 + 4 * 3 + 4 * 4 + 4 * 3 + 4;  // version 9 on: 8 more (hold, fall)
constexpr size_t kForceBytes = 1 + 4 + 4 + 4 + 4;   // with an empty name and instance
constexpr size_t kGroupBytes = 4 + 4;               // no bodies, no contacts
constexpr size_t kPairBytes = 8 + 4 + 4 + 4;        // no anchors (version 10 on: 16 more, drift and held gaps)
constexpr size_t kShapeBytes = 4 + 4;               // a sphere
constexpr size_t kSettingBytes = 4 + 4;             // an empty name and value

class Writer {
 public:
  std::vector<unsigned char> bytes;
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const unsigned char*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof v);
  }
  void put_floats(const float* p, size_t n) {
    for (size_t i = 0; i < n; ++i) put(p[i]);
  }
  void put_u32s(const std::vector<uint32_t>& v) {
    put(static_cast<uint32_t>(v.size()));
    for (uint32_t x : v) put(x);
  }
  void put_bytes(const void* p, size_t n) {
    put(static_cast<uint32_t>(n));
    bytes.insert(bytes.end(), static_cast<const unsigned char*>(p), static_cast<const unsigned char*>(p) + n);
  }
};

class Reader {
 public:
  Reader(const unsigned char* p, size_t n) : p_(p), n_(n) {}
  template <class T>
  T get(const char* what) {
    if (n_ - at_ < sizeof(T)) throw WorldError(std::string("snapshot: truncated at ") + what);
    T v;
    std::memcpy(&v, p_ + at_, sizeof v);
    at_ += sizeof v;
    return v;
  }
  void get_floats(float* out, size_t n, const char* what) {
    for (size_t i = 0; i < n; ++i) out[i] = get<float>(what);
  }
  uint32_t count(const char* what, size_t min_bytes_each) {
    const uint32_t c = get<uint32_t>(what);
    if (min_bytes_each && c > (n_ - at_) / min_bytes_each)
      throw WorldError(std::string("snapshot: ") + what + " count " + std::to_string(c) + " runs past the end (" +
                       std::to_string(n_ - at_) + " bytes left, at least " + std::to_string(min_bytes_each) + " each)");
    return c;
  }
  std::vector<uint32_t> get_u32s(const char* what) {
    std::vector<uint32_t> v(count(what, 4));
    for (uint32_t& x : v) x = get<uint32_t>(what);
    return v;
  }
  std::vector<unsigned char> get_bytes(const char* what) {
    const uint32_t c = count(what, 1);
    std::vector<unsigned char> v(p_ + at_, p_ + at_ + c);
    at_ += c;
    return v;
  }
  // A flag byte: 0 or 1, anything else is damage.
  bool get_flag(const std::string& who, const char* what) {
    const uint8_t v = get<uint8_t>(what);
    if (v > 1) throw WorldError("snapshot: " + who + ": " + what + " flag is " + std::to_string(v) + ", not 0 or 1");
    return v != 0;
  }
  bool done() const { return at_ == n_; }

 private:
  const unsigned char* p_;
  size_t n_, at_ = 0;
};

// A setting's value as the snapshot stores it.
std::vector<unsigned char> setting_bytes(const WorldSettings& s, const Setting& row) {
  const void* f = field_of(s, row);
  Writer w;
  switch (row.type) {
    case SettingType::f32: w.put(*static_cast<const float*>(f)); break;
    case SettingType::vec3: w.put_floats(static_cast<const float*>(f), 3); break;
    case SettingType::u32: w.put(*static_cast<const uint32_t*>(f)); break;
    case SettingType::i32: w.put(static_cast<int32_t>(*static_cast<const int*>(f))); break;
    case SettingType::size: w.put(static_cast<uint64_t>(*static_cast<const size_t*>(f))); break;
    case SettingType::boolean: w.put(static_cast<uint8_t>(*static_cast<const bool*>(f))); break;
    case SettingType::integrator: w.put(static_cast<uint32_t>(*static_cast<const spu::Integrator*>(f))); break;
    case SettingType::solver: w.put(static_cast<uint32_t>(*static_cast<const spu::Solver*>(f))); break;
  }
  return w.bytes;
}

void put_settings(Writer& w, const WorldSettings& s) {
  w.put(static_cast<uint32_t>(settings_table().size()));
  for (const Setting& row : settings_table()) {
    w.put_bytes(row.path.data(), row.path.size());
    const std::vector<unsigned char> value = setting_bytes(s, row);
    w.put_bytes(value.data(), value.size());
  }
}

WorldSettings get_settings(Reader& r, uint32_t version) {
  WorldSettings s;
  const std::vector<Setting>& table = settings_table();
  std::vector<bool> seen(table.size());
  const uint32_t n = r.count("settings", kSettingBytes);
  for (uint32_t k = 0; k < n; ++k) {
    const std::vector<unsigned char> name = r.get_bytes("setting name");
    const std::string path(name.begin(), name.end());
    const Setting* row = find_setting(path);
    if (!row) throw WorldError("snapshot: setting '" + path + "', which this build lacks");
    const size_t i = static_cast<size_t>(row - table.data());
    if (seen[i]) throw WorldError("snapshot: setting '" + path + "' given twice");
    seen[i] = true;
    const std::vector<unsigned char> value = r.get_bytes("setting value");
    const size_t want = setting_bytes(s, *row).size();
    if (value.size() != want)
      throw WorldError("snapshot: setting '" + path + "' has " + std::to_string(value.size()) + " bytes, this build's " +
                       std::to_string(want));
    Reader v(value.data(), value.size());
    void* f = field_of(s, *row);
    switch (row->type) {
      case SettingType::f32: *static_cast<float*>(f) = v.get<float>("setting"); break;
      case SettingType::vec3: v.get_floats(static_cast<float*>(f), 3, "setting"); break;
      case SettingType::u32: *static_cast<uint32_t*>(f) = v.get<uint32_t>("setting"); break;
      case SettingType::i32: *static_cast<int*>(f) = v.get<int32_t>("setting"); break;
      case SettingType::size: *static_cast<size_t*>(f) = static_cast<size_t>(v.get<uint64_t>("setting")); break;
      case SettingType::boolean: *static_cast<bool*>(f) = v.get<uint8_t>("setting") != 0; break;
      case SettingType::integrator:
      case SettingType::solver: {
        const uint32_t e = v.get<uint32_t>("setting");
        const std::string why = value_problem(*row, e);  // before it becomes an enum it does not name
        if (!why.empty()) throw WorldError("snapshot: setting '" + path + "': " + why);
        if (row->type == SettingType::integrator)
          *static_cast<spu::Integrator*>(f) = static_cast<spu::Integrator>(e);
        else
          *static_cast<spu::Solver*>(f) = static_cast<spu::Solver>(e);
        break;
      }
    }
  }
  for (size_t i = 0; i < table.size(); ++i) {
    if (seen[i]) continue;
    if (version < 7 && table[i].path == "whole_island_bytes") {
      s.whole_island_bytes = 0;  // a world saved when every big island was split steps on split
      continue;
    }
    if (version < 8 && table[i].path == "joint.projection") {
      s.joint_projection = 0;  // a world saved before joints were projected steps on without
      continue;
    }
    if (version < 9 && table[i].path == "contact.joined_hold_depth") {
      s.contact_joined_hold_depth = s.globals.contact_hold_depth;  // every contact held as then
      continue;
    }
    throw WorldError("snapshot: setting '" + table[i].path + "' is missing");
  }
  try {
    validate_settings(s);
  } catch (const WorldError& e) {
    throw WorldError(std::string("snapshot: ") + e.what());
  }
  return s;
}

void put_hull(Writer& w, const spu::HullView& h) {
  w.put(h.num_vertices);
  w.put_floats(h.vertices, 3 * size_t(h.num_vertices));
}

bool same_floats(const float* a, const float* b, size_t n) { return n == 0 || std::memcmp(a, b, 4 * n) == 0; }
bool same_ints(const int32_t* a, const int32_t* b, size_t n) { return n == 0 || std::memcmp(a, b, 4 * n) == 0; }

// Shapes are rebuilt through the dictionary's own constructors and must come out bit for
// bit as saved (spheres, capsules and boxes are stored as given; a plane's unit normal and a
// hull's centred vertices are fixed points of normalising and re-hulling, which is checked).
void put_shapes(Writer& w, const ShapeDictionary& d) {
  w.put(static_cast<uint32_t>(d.size()));
  for (uint32_t i = 0; i < d.size(); ++i) {
    const spu::ShapeView& v = d.view(i);
    w.put(static_cast<uint32_t>(v.type));
    switch (v.type) {
      case spu::ShapeType::sphere: w.put(v.radius); break;
      case spu::ShapeType::capsule: w.put(v.radius), w.put(v.half_height); break;
      case spu::ShapeType::box: w.put_floats(v.half_extents, 3); break;
      case spu::ShapeType::plane: w.put_floats(v.normal, 3), w.put(v.offset); break;
      case spu::ShapeType::hull: {
        put_hull(w, v.hull);
        // the whole hull, to check the rebuilt one against
        w.put(v.hull.num_faces);
        w.put_floats(v.hull.planes, 4 * size_t(v.hull.num_faces));
        w.put(v.hull.num_edges);
        const int32_t fv = v.hull.face_start[v.hull.num_faces];
        w.put(fv);
        for (int k = 0; k <= v.hull.num_faces; ++k) w.put(v.hull.face_start[k]);
        for (int k = 0; k < fv; ++k) w.put(v.hull.face_vertices[k]);
        for (int k = 0; k < 2 * v.hull.num_edges; ++k) w.put(v.hull.edges[k]);
        break;
      }
      case spu::ShapeType::mesh: {
        const SurfaceInput& in = d.surface_input(i);
        w.put(static_cast<int32_t>(in.vertices.size() / 3));
        w.put_floats(in.vertices.data(), in.vertices.size());
        w.put(static_cast<int32_t>(in.triangles.size() / 3));
        for (int32_t x : in.triangles) w.put(x);
        w.put(in.num_triangles);  // to check the rebuilt surface against
        break;
      }
      case spu::ShapeType::compound: {
        const std::vector<CompoundPart>& parts = d.compound_parts(i);
        w.put(static_cast<uint32_t>(parts.size()));
        for (const CompoundPart& p : parts) {
          w.put(p.shape);
          w.put_floats(p.position, 3);
          w.put_floats(p.orientation, 4);
          w.put(p.scale);
        }
        break;
      }
      case spu::ShapeType::height_field: {
        const SurfaceInput& in = d.surface_input(i);
        w.put(in.rows), w.put(in.columns);
        w.put_floats(in.spacing, 2);
        w.put_floats(in.heights.data(), in.heights.size());
        w.put(in.num_triangles);
        break;
      }
    }
  }
}

void get_shapes(Reader& r, ShapeDictionary& d, uint32_t version) {
  const uint32_t n = r.count("shapes", kShapeBytes);
  for (uint32_t i = 0; i < n; ++i) {
    const std::string who = "snapshot: shape " + std::to_string(i);
    const uint32_t type = r.get<uint32_t>("shape type");
    try {
      switch (static_cast<spu::ShapeType>(type)) {
        case spu::ShapeType::sphere: d.add_sphere(r.get<float>("sphere")); break;
        case spu::ShapeType::capsule: {
          const float radius = r.get<float>("capsule"), half = r.get<float>("capsule");
          d.add_capsule(radius, half);
          break;
        }
        case spu::ShapeType::box: {
          float h[3];
          r.get_floats(h, 3, "box");
          d.add_box(h);
          break;
        }
        case spu::ShapeType::plane: {
          float nrm[3];
          r.get_floats(nrm, 3, "plane");
          const float offset = r.get<float>("plane");
          const spu::ShapeView& v = d.view(d.add_plane(nrm, offset));
          if (!same_floats(v.normal, nrm, 3)) throw WorldError(who + ": plane normal does not rebuild bit for bit");
          break;
        }
        case spu::ShapeType::hull: {
          const int32_t nv = r.get<int32_t>("hull");
          if (nv < 4 || nv > 1 << 20) throw WorldError(who + ": hull vertex count out of range");
          std::vector<float> verts(3 * size_t(nv));
          r.get_floats(verts.data(), verts.size(), "hull vertices");
          const int32_t nf = r.get<int32_t>("hull");
          if (nf < 4 || nf > 1 << 20) throw WorldError(who + ": hull face count out of range");
          std::vector<float> planes(4 * size_t(nf));
          r.get_floats(planes.data(), planes.size(), "hull planes");
          const int32_t ne = r.get<int32_t>("hull"), nfv = r.get<int32_t>("hull");
          if (ne < 0 || ne > 1 << 20 || nfv < 0 || nfv > 1 << 22) throw WorldError(who + ": hull counts out of range");
          std::vector<int32_t> fs(size_t(nf) + 1), fvs(static_cast<size_t>(nfv)), edges(2 * size_t(ne));
          for (int32_t& x : fs) x = r.get<int32_t>("hull faces");
          for (int32_t& x : fvs) x = r.get<int32_t>("hull faces");
          for (int32_t& x : edges) x = r.get<int32_t>("hull edges");
          const spu::HullView& h = d.view(d.add_hull(verts.data(), nv, nullptr, /*recentre=*/false)).hull;
          if (h.num_vertices != nv || h.num_faces != nf || h.num_edges != ne || h.face_start[nf] != nfv ||
              !same_floats(h.vertices, verts.data(), verts.size()) || !same_floats(h.planes, planes.data(), planes.size()) ||
              !same_ints(h.face_start, fs.data(), fs.size()) || !same_ints(h.face_vertices, fvs.data(), fvs.size()) ||
              !same_ints(h.edges, edges.data(), edges.size()))
            throw WorldError(who + ": hull does not rebuild bit for bit from its vertices");
          break;
        }
        case spu::ShapeType::mesh: {
          if (version < 6) throw WorldError(who + ": a mesh in a version " + std::to_string(version) + " snapshot");
          const uint32_t nv = r.count("mesh vertices", 12);
          std::vector<float> verts(3 * size_t(nv));
          r.get_floats(verts.data(), verts.size(), "mesh vertices");
          const uint32_t nt = r.count("mesh triangles", 12);
          std::vector<int32_t> tris(3 * size_t(nt));
          for (int32_t& x : tris) x = r.get<int32_t>("mesh triangles");
          const int32_t kept = r.get<int32_t>("mesh");
          const uint32_t index = d.add_mesh(verts.data(), int(nv), tris.data(), int(nt));
          if (d.surface_input(index).num_triangles != kept) throw WorldError(who + ": mesh does not rebuild as saved");
          break;
        }
        case spu::ShapeType::height_field: {
          if (version < 6) throw WorldError(who + ": a height field in a version " + std::to_string(version) + " snapshot");
          const int32_t rows = r.get<int32_t>("height field"), columns = r.get<int32_t>("height field");
          if (rows < 2 || columns < 2 || int64_t(rows) * columns > (1 << 22))
            throw WorldError(who + ": height field grid out of range");
          float spacing[2];
          r.get_floats(spacing, 2, "height field");
          std::vector<float> heights(size_t(rows) * size_t(columns));
          r.get_floats(heights.data(), heights.size(), "height field heights");
          const int32_t kept = r.get<int32_t>("height field");
          const uint32_t index = d.add_height_field(rows, columns, spacing, heights.data());
          if (d.surface_input(index).num_triangles != kept) throw WorldError(who + ": height field does not rebuild as saved");
          break;
        }
        case spu::ShapeType::compound: {
          if (version < 6) throw WorldError(who + ": a compound in a version " + std::to_string(version) + " snapshot");
          const uint32_t np = r.count("compound parts", 36);
          if (np < 1 || np > uint32_t(kMaxCompoundParts)) throw WorldError(who + ": compound part count out of range");
          std::vector<CompoundPart> parts(np);
          for (CompoundPart& p : parts) {
            p.shape = r.get<uint32_t>("compound part");
            if (p.shape >= i) throw WorldError(who + ": a compound part names a shape not before it");
            r.get_floats(p.position, 3, "compound part");
            r.get_floats(p.orientation, 4, "compound part");
            p.scale = r.get<float>("compound part");
          }
          const std::vector<CompoundPart>& got = d.compound_parts(d.add_compound(parts.data(), int(np), nullptr, false));
          for (uint32_t k = 0; k < np; ++k)
            if (!same_floats(got[k].orientation, parts[k].orientation, 4) || !same_floats(got[k].position, parts[k].position, 3))
              throw WorldError(who + ": compound does not rebuild bit for bit");
          break;
        }
        default: throw WorldError(who + ": unknown shape type " + std::to_string(type));
      }
    } catch (const ShapeError& e) {
      throw WorldError(who + ": " + e.what());
    }
  }
}

void put_state(Writer& w, const BodyState& s) {
  w.put_floats(s.position, 3);
  w.put_floats(s.orientation, 4);
  w.put_floats(s.velocity, 3);
  w.put_floats(s.angular_velocity, 3);
}

void get_state(Reader& r, BodyState& s) {
  r.get_floats(s.position, 3, "body");
  r.get_floats(s.orientation, 4, "body");
  r.get_floats(s.velocity, 3, "body");
  r.get_floats(s.angular_velocity, 3, "body");
}

void put_contact(Writer& w, const WorldContact& c) {
  w.put(c.a);
  w.put(c.b);
  w.put_floats(c.point.point, 3);
  w.put_floats(c.point.normal, 3);
  w.put(c.point.penetration);
  w.put(c.friction);
  w.put(c.mass);
  w.put(c.load);
  w.put_floats(c.anchor, 3);
  w.put(c.sticking);
  w.put(c.hold);
  w.put(c.fall);
}

void put_anchor(Writer& w, const ContactMemory::Anchor& a) {
  w.put_floats(a.on_a, 3);
  w.put_floats(a.on_b, 3);
}

ContactMemory::Anchor get_anchor(Reader& r) {
  ContactMemory::Anchor a;
  r.get_floats(a.on_a, 3, "contact anchor");
  r.get_floats(a.on_b, 3, "contact anchor");
  return a;
}

WorldContact get_contact(Reader& r, uint32_t version, const WorldSettings& s) {
  WorldContact c;
  c.a = r.get<uint32_t>("contact");
  c.b = r.get<uint32_t>("contact");
  r.get_floats(c.point.point, 3, "contact");
  r.get_floats(c.point.normal, 3, "contact");
  c.point.penetration = r.get<float>("contact");
  c.friction = r.get<float>("contact");
  c.mass = r.get<float>("contact");
  c.load = r.get<float>("contact");
  r.get_floats(c.anchor, 3, "contact");
  c.sticking = r.get<float>("contact");
  c.hold = version < 9 ? s.globals.contact_hold_depth : r.get<float>("contact");
  c.fall = version < 9 ? gravity_fall(c.point.normal, c.b == kWorldBody, s) : r.get<float>("contact");
  return c;
}

}  // namespace

std::vector<unsigned char> World::snapshot() const {
  const Impl& w = *impl_;
  Writer p;
  put_settings(p, settings_);
  p.put(static_cast<uint64_t>(stats_.step));
  put_shapes(p, shapes_);
  p.put(static_cast<uint32_t>(w.bodies.size()));
  for (const WorldBody& b : w.bodies) {
    p.put(static_cast<uint8_t>(b.alive));
    p.put(static_cast<uint8_t>(b.is_static));
    p.put(static_cast<uint8_t>(b.awake));
    p.put(static_cast<uint8_t>(b.sensor ? 1 : 0));
    p.put(b.shape);
    p.put(b.scale);
    p.put(b.mass);
    p.put_floats(b.inertia, 6);
    p.put_floats(b.inverse_inertia, 6);
    put_state(p, b.state);
    p.put(b.friction);
    p.put(b.linear_damping);
    p.put(b.angular_damping);
    p.put(b.sleep_timer);
    p.put(b.sleep_group);
  }
  p.put(static_cast<uint32_t>(w.forces.size()));
  for (const WorldForce& f : w.forces) {
    p.put(static_cast<uint8_t>(f.alive));
    const char* name = gen::kForceTable[static_cast<int>(f.type)].name;
    p.put_bytes(name, std::strlen(name));  // by name: a force table reordered by a rebuild still reads
    p.put(f.a);
    p.put(f.b);
    p.put_bytes(f.instance.data(), f.instance.size());
  }
  p.put(static_cast<uint32_t>(w.sleeping.groups.size()));
  for (const SleepGroup& g : w.sleeping.groups) {
    p.put_u32s(g.bodies);
    p.put(static_cast<uint32_t>(g.contacts.size()));
    for (const WorldContact& c : g.contacts) put_contact(p, c);
  }
  p.put(static_cast<uint32_t>(w.sleeping.free.size()));
  for (int32_t g : w.sleeping.free) p.put(g);
  std::vector<uint64_t> keys;  // in key order: the same world writes the same bytes
  for (const auto& kv : w.contact_memory.pairs) keys.push_back(kv.first);
  std::sort(keys.begin(), keys.end());
  p.put(static_cast<uint32_t>(keys.size()));
  for (uint64_t key : keys) {
    const ContactMemory::Pair& pair = w.contact_memory.pairs.at(key);
    p.put(key);
    p.put(pair.sliding);
    p.put(pair.slip);
    for (float d : pair.drift) p.put(d);
    p.put(pair.held_gaps);
    p.put(pair.count);
    for (uint32_t k = 0; k < pair.count; ++k) put_anchor(p, pair.anchors[k]);
  }
  const std::vector<uint64_t> touching = touching_pairs(w.event_memory);
  for (const std::vector<uint64_t>* keys : {&touching, &w.event_memory.sensing}) {
    p.put(static_cast<uint32_t>(keys->size()));
    for (uint64_t k : *keys) p.put(k);
  }

  Writer out;
  out.bytes.insert(out.bytes.end(), kMagic, kMagic + 8);
  out.put(kVersion);
  out.put(static_cast<uint32_t>(kHeaderBytes));
  out.put(static_cast<uint64_t>(p.bytes.size()));
  out.put(spu::checksum(p.bytes.data(), p.bytes.size()));
  out.put(uint32_t{0});
  out.bytes.insert(out.bytes.end(), p.bytes.begin(), p.bytes.end());
  return out.bytes;
}

std::unique_ptr<World> World::restore(const unsigned char* bytes, size_t size) {
  if (!bytes || size < kHeaderBytes) throw WorldError("snapshot: shorter than its header");
  if (std::memcmp(bytes, kMagic, 8) != 0) throw WorldError("snapshot: bad magic (not a cellphys world snapshot)");
  Reader h(bytes + 8, kHeaderBytes - 8);
  const uint32_t version = h.get<uint32_t>("header");
  if (version < kOldestVersion || version > kVersion)
    throw WorldError("snapshot: format version " + std::to_string(version) + ", this build reads " +
                     std::to_string(kOldestVersion) + " to " + std::to_string(kVersion));
  if (h.get<uint32_t>("header") != kHeaderBytes) throw WorldError("snapshot: unexpected header size");
  const uint64_t payload = h.get<uint64_t>("header");
  const uint32_t sum = h.get<uint32_t>("header");
  if (payload != size - kHeaderBytes)
    throw WorldError("snapshot: header says " + std::to_string(payload) + " payload bytes, got " + std::to_string(size - kHeaderBytes));
  if (spu::checksum(bytes + kHeaderBytes, payload) != sum) throw WorldError("snapshot: checksum mismatch");

  Reader r(bytes + kHeaderBytes, payload);
  const WorldSettings settings = get_settings(r, version);
  auto world = std::make_unique<World>(settings);
  World& W = *world;
  Impl& w = *W.impl_;
  W.stats_.step = r.get<uint64_t>("step counter");
  get_shapes(r, W.shapes_, version);

  const uint32_t nb = r.count("bodies", kBodyBytes);
  w.bodies.resize(nb);
  for (uint32_t i = 0; i < nb; ++i) {
    WorldBody& b = w.bodies[i];
    const std::string who = body_name(i);
    b.alive = r.get_flag(who, "alive");
    b.is_static = r.get_flag(who, "static");
    b.awake = r.get_flag(who, "awake");
    const uint8_t flags = r.get<uint8_t>("body");
    if (flags > (version >= 5 ? 1 : 0)) throw WorldError("snapshot: " + who + ": unknown body flags " + std::to_string(flags));
    b.sensor = flags & 1;
    b.shape = r.get<uint32_t>("body");
    b.scale = r.get<float>("body");
    b.mass = r.get<float>("body");
    r.get_floats(b.inertia, 6, "body");
    r.get_floats(b.inverse_inertia, 6, "body");
    get_state(r, b.state);
    b.friction = r.get<float>("body");
    b.linear_damping = r.get<float>("body");
    b.angular_damping = r.get<float>("body");
    b.sleep_timer = r.get<float>("body");
    b.sleep_group = r.get<int32_t>("body");
    check_snapshot_body(W.shapes_, b, i);
  }

  const uint32_t nf = r.count("forces", kForceBytes);
  w.forces.resize(nf);
  for (uint32_t i = 0; i < nf; ++i) {
    WorldForce& f = w.forces[i];
    f.alive = r.get_flag("force " + std::to_string(i), "alive");
    const std::vector<unsigned char> name = r.get_bytes("force type");
    const std::string type(name.begin(), name.end());
    int t = -1;
    for (int k = 0; k < gen::kNumForceTypes; ++k)
      if (type == gen::kForceTable[k].name) t = k;
    if (t < 0) throw WorldError("snapshot: force " + std::to_string(i) + " has type '" + type + "', which this build lacks");
    f.type = static_cast<gen::ForceType>(t);
    f.a = r.get<uint32_t>("force");
    f.b = r.get<uint32_t>("force");
    f.instance = r.get_bytes("force instance");
    if (f.instance.size() != gen::kForceTable[t].instance_size)
      throw WorldError("snapshot: force " + std::to_string(i) + " (" + type + ") has a different layout in this build");
    check_snapshot_force(w.bodies, f, i);
  }

  const uint32_t ng = r.count("sleeping groups", kGroupBytes);
  w.sleeping.groups.resize(ng);
  for (uint32_t g = 0; g < ng; ++g) {
    w.sleeping.groups[g].bodies = r.get_u32s("sleeping group");
    const uint32_t nc = r.count("sleeping contacts", kContactBytes);
    for (uint32_t c = 0; c < nc; ++c) {
      w.sleeping.groups[g].contacts.push_back(get_contact(r, version, settings));
      check_snapshot_contact(w.bodies, w.sleeping.groups[g].contacts.back(), g, c);
    }
  }
  const uint32_t nfree = r.count("free groups", 4);
  for (uint32_t k = 0; k < nfree; ++k) w.sleeping.free.push_back(r.get<int32_t>("free groups"));
  check_snapshot_sleeping(w.bodies, w.sleeping);
  const uint32_t npairs = r.count("contact memory", kPairBytes);
  for (uint32_t k = 0; k < npairs; ++k) {
    const uint64_t key = r.get<uint64_t>("contact memory");
    ContactMemory::Pair pair;
    pair.sliding = r.get<uint32_t>("contact memory");
    pair.slip = r.get<float>("contact memory");
    if (version >= 10) {
      for (float& d : pair.drift) d = r.get<float>("contact memory");
      pair.held_gaps = r.get<uint32_t>("contact memory");
    }
    pair.count = r.get<uint32_t>("contact memory");
    if (pair.count > spu::kMaxManifoldPoints) check_snapshot_pair(w.bodies, key, pair);  // refuses it by name
    for (uint32_t a = 0; a < pair.count; ++a) pair.anchors[a] = get_anchor(r);
    check_snapshot_pair(w.bodies, key, pair);
    if (!w.contact_memory.pairs.emplace(key, pair).second)
      throw WorldError("snapshot: the contact memory holds a pair twice (key " + std::to_string(key) + ")");
  }
  if (version >= 5) {
    std::vector<uint64_t>* memories[2] = {&w.event_memory.touching, &w.event_memory.sensing};
    const char* what[2] = {"touching pairs", "sensor overlaps"};
    for (int m = 0; m < 2; ++m) {
      const uint32_t n = r.count(what[m], 8);
      for (uint32_t k = 0; k < n; ++k) memories[m]->push_back(r.get<uint64_t>(what[m]));
      check_snapshot_event_pairs(w.bodies, *memories[m], m == 1, what[m]);
    }
  }
  if (!r.done()) throw WorldError("snapshot: trailing bytes after the last record");
  return world;
}

}  // namespace cellphys::ppe
