#include "server/state_encoder.h"

#include <cstddef>
#include <cstring>

#include "server/quantise.h"

namespace cellphys::server {

namespace {

using namespace protocol;

template <class T>
void put(std::vector<unsigned char>& out, const T& v) {
  const size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));
}

template <class T>
void put_at(std::vector<unsigned char>& out, size_t at, const T& v) {
  std::memcpy(out.data() + at, &v, sizeof(T));
}

void put_floats(std::vector<unsigned char>& out, const float* v, size_t n) {
  const size_t at = out.size();
  out.resize(at + 4 * n);
  if (n) std::memcpy(out.data() + at, v, 4 * n);
}

void pad4(std::vector<unsigned char>& out) {
  while (out.size() % 4) out.push_back(0);
}

Header header(Type t) { return Header{0, static_cast<uint16_t>(t), kVersion}; }

void seal(std::vector<unsigned char>& out, size_t start) {
  put_at(out, start, static_cast<uint32_t>(out.size() - start));
}

BodyFull full(const FrameBody& b) {
  BodyFull r;
  r.id = b.id;
  r.shape = b.shape;
  r.scale = b.scale;
  r.flags = b.flags;
  ppe::copy_state(b.state, r);
  return r;
}

}  // namespace

bool Interest::contains(const FrameBody& b) const {
  if (!region || (b.flags & kBodyUnbounded)) return true;
  for (int k = 0; k < 3; ++k)
    if (!(b.state.position[k] >= min[k] && b.state.position[k] <= max[k])) return false;
  return true;
}

std::vector<unsigned char> encode_shapes(const ppe::ShapeDictionary& shapes) {
  std::vector<unsigned char> out;
  for (uint32_t i = 0; i < shapes.size(); ++i) {
    const spu::ShapeView& v = shapes.view(i);
    ShapeRecord r{};
    r.type = static_cast<uint32_t>(v.type);
    switch (v.type) {
      case spu::ShapeType::sphere: r.params[0] = v.radius; break;
      case spu::ShapeType::capsule:
        r.params[0] = v.radius;
        r.params[1] = v.half_height;
        break;
      case spu::ShapeType::box:
        for (int k = 0; k < 3; ++k) r.params[k] = v.half_extents[k];
        break;
      case spu::ShapeType::plane:
        for (int k = 0; k < 3; ++k) r.params[k] = v.normal[k];
        r.params[3] = v.offset;
        break;
      case spu::ShapeType::hull:
        r.num_vertices = static_cast<uint32_t>(v.hull.num_vertices);
        r.num_faces = static_cast<uint32_t>(v.hull.num_faces);
        r.num_face_vertices = static_cast<uint32_t>(v.hull.face_start[v.hull.num_faces]);
        break;
      case spu::ShapeType::mesh:
      case spu::ShapeType::height_field:  // its triangles, as a hull's faces of 3: a client draws both alike
        r.num_vertices = static_cast<uint32_t>(v.mesh.num_vertices);
        r.num_faces = static_cast<uint32_t>(v.mesh.num_triangles);
        r.num_face_vertices = 3 * r.num_faces;
        break;
      case spu::ShapeType::compound: r.num_vertices = static_cast<uint32_t>(v.compound.num_parts); break;
    }
    put(out, r);
    if (v.type == spu::ShapeType::hull) {
      put_floats(out, v.hull.vertices, 3 * r.num_vertices);
      for (uint32_t k = 0; k <= r.num_faces; ++k) put(out, static_cast<uint32_t>(v.hull.face_start[k]));
      for (uint32_t k = 0; k < r.num_face_vertices; ++k) put(out, static_cast<uint32_t>(v.hull.face_vertices[k]));
    } else if (spu::is_triangle_surface(v.type)) {
      put_floats(out, v.mesh.vertices, 3 * r.num_vertices);
      for (uint32_t k = 0; k <= r.num_faces; ++k) put(out, 3 * k);
      for (uint32_t k = 0; k < r.num_face_vertices; ++k) put(out, static_cast<uint32_t>(v.mesh.triangles[k]));
    } else if (v.type == spu::ShapeType::compound) {
      // The parts as stored, re-centred: a part names its shape by index, and the dictionary
      // takes only shapes it already holds, so that index is always an earlier record's.
      for (const ppe::CompoundPart& p : shapes.compound_parts(i)) {
        CompoundPartRecord c;
        c.shape = p.shape;
        std::memcpy(c.position, p.position, sizeof c.position);
        std::memcpy(c.orientation, p.orientation, sizeof c.orientation);
        c.scale = p.scale;
        put(out, c);
      }
    }
  }
  return out;
}

RevisionNeed revision_needed(const ppe::ShapeDictionary& shapes) {
  RevisionNeed r;
  for (uint32_t i = 0; i < shapes.size(); ++i) {
    const uint32_t need = shape_revision(static_cast<uint32_t>(shapes.type(i)));
    if (need > r.revision) r = {need, i, shapes.type(i)};
  }
  return r;
}

void encode_join(const Frame& f, const Interest& in, bool can_command, std::vector<uint32_t>& known,
                 std::vector<unsigned char>& out) {
  const size_t start = out.size();
  Join j{};
  j.header = header(Type::join);
  j.epoch = f.epoch;
  j.flags = can_command ? kJoinCanCommand : 0u;
  j.step = f.step;
  j.dt = f.dt;
  j.tick_hz = f.tick_hz;
  j.num_shapes = f.num_shapes;
  j.revision = kRevision;
  j.name_bytes = static_cast<uint32_t>((f.world.size() + 3) / 4 * 4);
  put(out, j);
  out.insert(out.end(), f.world.begin(), f.world.end());
  pad4(out);
  if (f.shapes) out.insert(out.end(), f.shapes->begin(), f.shapes->end());
  known.clear();
  for (const FrameBody& b : f.bodies)
    if (in.contains(b)) {
      put(out, full(b));
      known.push_back(b.id);
    }
  put_at(out, start + offsetof(Join, num_bodies), static_cast<uint32_t>(known.size()));
  seal(out, start);
}

void encode_tick(const Frame& f, const Interest& in, uint64_t since, uint32_t skipped, std::vector<uint32_t>& known,
                 std::vector<unsigned char>& out) {
  std::vector<const FrameBody*> entered, moved;
  std::vector<uint32_t> gone, now;
  now.reserve(f.bodies.size());
  size_t k = 0;  // merge of the held ids with the frame's, both ascending
  for (const FrameBody& b : f.bodies) {
    while (k < known.size() && known[k] < b.id) gone.push_back(known[k++]);  // removed from the world
    const bool held = k < known.size() && known[k] == b.id;
    if (held) ++k;
    if (!in.contains(b)) {
      if (held) gone.push_back(b.id);
      continue;
    }
    now.push_back(b.id);
    if (!held)
      entered.push_back(&b);
    else if (b.changed > since)
      moved.push_back(&b);
  }
  while (k < known.size()) gone.push_back(known[k++]);
  known.swap(now);

  const size_t start = out.size();
  Tick t{};
  t.header = header(Type::tick);
  t.step = f.step;
  t.epoch = f.epoch;
  t.flags = (in.quantised ? kTickQuantised : 0u) | (f.paused ? kTickPaused : 0u);
  t.skipped = skipped;
  t.num_entered = static_cast<uint32_t>(entered.size());
  t.num_moved = static_cast<uint32_t>(moved.size());
  t.num_gone = static_cast<uint32_t>(gone.size());
  t.stats = f.stats;
  if (in.quantised) {
    std::vector<const ppe::BodyState*> states(moved.size());
    for (size_t i = 0; i < moved.size(); ++i) states[i] = &moved[i]->state;
    t.quant = quant_frame(states.data(), states.size());
  }
  out.reserve(start + sizeof t + entered.size() * sizeof(BodyFull) + moved.size() * sizeof(BodyMoved) + 4 * gone.size());
  put(out, t);
  for (const FrameBody* b : entered) put(out, full(*b));
  for (const FrameBody* b : moved) {
    if (in.quantised) {
      BodyMovedQ q;
      q.id = b->id;
      quantise(b->state, t.quant, q);
      put(out, q);
    } else {
      BodyMoved m;
      m.id = b->id;
      ppe::copy_state(b->state, m);
      put(out, m);
    }
  }
  for (uint32_t id : gone) put(out, id);
  seal(out, start);
}

std::shared_ptr<const std::vector<unsigned char>> shared_tick(const Frame& f, bool quantised, uint64_t since,
                                                              std::vector<uint32_t>& known) {
  {
    std::lock_guard<std::mutex> lock(f.cache_mutex);
    for (const Frame::Encoded& e : f.cache)
      if (e.from == since && e.quantised == quantised) {
        known.clear();
        for (const FrameBody& b : f.bodies) known.push_back(b.id);
        return e.bytes;
      }
  }
  Interest in;
  in.quantised = quantised;
  auto bytes = std::make_shared<std::vector<unsigned char>>();
  encode_tick(f, in, since, 0, known, *bytes);
  std::lock_guard<std::mutex> lock(f.cache_mutex);
  f.cache.push_back({since, quantised, bytes});
  return bytes;
}

void set_skipped(std::vector<unsigned char>& tick, uint32_t skipped) { put_at(tick, offsetof(Tick, skipped), skipped); }

}  // namespace cellphys::server
