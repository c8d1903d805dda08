#include "server/message_decode.h"

#include <cstring>

#include "runtime/spu/shape.h"
#include "server/quantise.h"

namespace cellphys::server {

namespace {

using namespace protocol;

// Reads sequentially from a message, refusing to run past its end.
class Reader {
 public:
  Reader(const unsigned char* p, size_t n) : p_(p), n_(n) {}
  template <class T>
  bool get(T& v) {
    if (n_ - at_ < sizeof(T)) return false;
    std::memcpy(&v, p_ + at_, sizeof(T));
    at_ += sizeof(T);
    return true;
  }
  bool bytes(size_t n, std::string& s) {
    if (n_ - at_ < n) return false;
    s.assign(reinterpret_cast<const char*>(p_ + at_), n);
    at_ += n;
    return true;
  }
  bool skip(size_t n) {
    if (n_ - at_ < n) return false;
    at_ += n;
    return true;
  }
  bool done() const { return at_ == n_; }
  size_t left() const { return n_ - at_; }

 private:
  const unsigned char* p_;
  size_t n_, at_ = 0;
};

std::string check_header(const unsigned char* data, size_t size, Type type) {
  Header h;
  if (size < sizeof h) return "shorter than a header";
  std::memcpy(&h, data, sizeof h);
  if (h.length != size) return "header.length " + std::to_string(h.length) + " is not the message's " + std::to_string(size);
  if (h.version != kVersion) return "version " + std::to_string(h.version);
  if (h.type != static_cast<uint16_t>(type))
    return std::string("a ") + type_name(h.type) + " message, not a " + type_name(static_cast<uint16_t>(type));
  return "";
}

size_t padded(size_t n) { return (n + 3) / 4 * 4; }

}  // namespace

uint16_t message_type(const unsigned char* data, size_t size) {
  if (size < sizeof(Header)) return 0;
  Header h;
  std::memcpy(&h, data, sizeof h);
  return h.type;
}

std::string decode_join(const unsigned char* data, size_t size, JoinMessage& out) {
  if (auto e = check_header(data, size, Type::join); !e.empty()) return e;
  Reader r(data, size);
  out = JoinMessage{};
  if (!r.get(out.head)) return "cut in its fixed part";
  std::string name;
  if (!r.bytes(out.head.name_bytes, name)) return "cut in the name";
  out.world = name.substr(0, name.find('\0'));
  for (uint32_t i = 0; i < out.head.num_shapes; ++i) {
    ShapeRecord s;
    if (!r.get(s)) return "cut in shape " + std::to_string(i);
    const std::string shape = "shape " + std::to_string(i);
    if (s.type == static_cast<uint32_t>(spu::ShapeType::compound)) {
      // num_vertices counts the parts; the count checked against what is left before sizing by it.
      if (s.num_faces || s.num_face_vertices) return "compound " + shape + " has faces";
      if (s.num_vertices == 0) return "compound " + shape + " has no parts";
      if (sizeof(CompoundPartRecord) * size_t(s.num_vertices) > r.left()) return "cut in the parts of " + shape;
      std::vector<CompoundPartRecord> parts(s.num_vertices);
      for (size_t k = 0; k < parts.size(); ++k) {
        if (!r.get(parts[k])) return "cut in the parts of " + shape;
        // An earlier shape, and a convex one, so a client resolves every part on the way.
        const uint32_t of = parts[k].shape;
        if (of >= i) return shape + " part " + std::to_string(k) + " names shape " + std::to_string(of) + ", not an earlier one";
        if (!spu::is_convex(static_cast<spu::ShapeType>(out.shapes[of].type)))
          return shape + " part " + std::to_string(k) + " names shape " + std::to_string(of) + ", which is not convex";
      }
      out.shapes.push_back(s);
      out.vertices.emplace_back();
      out.face_start.emplace_back();
      out.face_vertices.emplace_back();
      out.parts.push_back(std::move(parts));
      continue;
    }
    const bool faces = s.type == static_cast<uint32_t>(spu::ShapeType::hull) ||
                       spu::is_triangle_surface(static_cast<spu::ShapeType>(s.type));
    // The counts checked against what is left before anything is sized by them.
    const size_t want = 12 * size_t(s.num_vertices) + (faces ? 4 * (size_t(s.num_faces) + 1 + s.num_face_vertices) : 0);
    if (want > r.left()) return "cut in the vertices and faces of shape " + std::to_string(i);
    std::vector<float> v(3 * size_t(s.num_vertices));
    std::vector<uint32_t> start(faces ? size_t(s.num_faces) + 1 : 0), loops(faces ? s.num_face_vertices : 0);
    for (float& x : v)
      if (!r.get(x)) return "cut in the vertices of shape " + std::to_string(i);
    for (uint32_t& x : start)
      if (!r.get(x)) return "cut in the faces of shape " + std::to_string(i);
    for (uint32_t& x : loops)
      if (!r.get(x)) return "cut in the faces of shape " + std::to_string(i);
    out.shapes.push_back(s);
    out.vertices.push_back(std::move(v));
    out.face_start.push_back(std::move(start));
    out.face_vertices.push_back(std::move(loops));
    out.parts.emplace_back();
  }
  out.bodies.resize(out.head.num_bodies);
  for (BodyFull& b : out.bodies)
    if (!r.get(b)) return "cut in the bodies";
  if (!r.done()) return "bytes after the bodies";
  return "";
}

std::string decode_tick(const unsigned char* data, size_t size, TickMessage& out) {
  if (auto e = check_header(data, size, Type::tick); !e.empty()) return e;
  Reader r(data, size);
  out = TickMessage{};
  if (!r.get(out.head)) return "cut in its fixed part";
  out.entered.resize(out.head.num_entered);
  for (BodyFull& b : out.entered)
    if (!r.get(b)) return "cut in entered";
  const bool quantised = (out.head.flags & kTickQuantised) != 0;
  for (uint32_t i = 0; i < out.head.num_moved; ++i) {
    ppe::BodyState s;
    uint32_t id;
    if (quantised) {
      BodyMovedQ q;
      if (!r.get(q)) return "cut in moved";
      dequantise(q, out.head.quant, s);
      id = q.id;
    } else {
      BodyMoved m;
      if (!r.get(m)) return "cut in moved";
      ppe::copy_state(m, s);
      id = m.id;
    }
    out.moved.emplace_back(id, s);
  }
  out.gone.resize(out.head.num_gone);
  for (uint32_t& id : out.gone)
    if (!r.get(id)) return "cut in gone";
  if (!r.done()) return "bytes after gone";
  return "";
}

std::string decode_ack(const unsigned char* data, size_t size, Ack& out) {
  if (auto e = check_header(data, size, Type::ack); !e.empty()) return e;
  if (size != sizeof out) return "not " + std::to_string(sizeof out) + " bytes";
  std::memcpy(&out, data, sizeof out);
  return "";
}

std::string decode_error(const unsigned char* data, size_t size, ErrorMessage& out) {
  if (auto e = check_header(data, size, Type::error); !e.empty()) return e;
  Reader r(data, size);
  if (!r.get(out.head)) return "cut in its fixed part";
  if (!r.bytes(out.head.field_bytes, out.field) || !r.bytes(out.head.reason_bytes, out.reason)) return "cut in its text";
  if (size != padded(sizeof out.head + out.head.field_bytes + out.head.reason_bytes)) return "bytes after its text";
  return "";
}

std::string decode_status(const unsigned char* data, size_t size, StatusMessage& out) {
  if (auto e = check_header(data, size, Type::status); !e.empty()) return e;
  Reader r(data, size);
  if (!r.get(out.head)) return "cut in its fixed part";
  if (!r.bytes(out.head.text_bytes, out.text)) return "cut in its text";
  if (size != padded(sizeof out.head + out.head.text_bytes)) return "bytes after its text";
  return "";
}

std::string decode_debug(const unsigned char* data, size_t size, DebugMessage& out) {
  if (auto e = check_header(data, size, Type::debug); !e.empty()) return e;
  Reader r(data, size);
  out = DebugMessage{};
  if (!r.get(out.head)) return "cut in its fixed part";
  out.bodies.resize(out.head.num_bodies);
  for (DebugBody& b : out.bodies)
    if (!r.get(b)) return "cut in the bodies";
  out.contacts.resize(out.head.num_contacts);
  for (DebugContact& c : out.contacts)
    if (!r.get(c)) return "cut in the contacts";
  out.cuts.resize(out.head.num_cuts);
  for (DebugCut& c : out.cuts)
    if (!r.get(c)) return "cut in the cut couplings";
  if (!r.done()) return "bytes after the cut couplings";
  return "";
}

std::string decode_stages(const unsigned char* data, size_t size, StagesMessage& out) {
  if (auto e = check_header(data, size, Type::stages); !e.empty()) return e;
  Reader r(data, size);
  out = StagesMessage{};
  if (!r.get(out.head)) return "cut in its fixed part";
  std::vector<float> ms(out.head.num_stages);
  for (float& v : ms)
    if (!r.get(v)) return "cut in the times";
  std::string names;
  if (out.head.names_bytes % 4 || !r.bytes(out.head.names_bytes, names)) return "cut in the names";
  if (!r.done()) return "bytes after the names";
  size_t at = 0;
  for (uint32_t k = 0; k < out.head.num_stages; ++k) {
    const size_t end = names.find('\0', at);
    if (end == std::string::npos) return "stage " + std::to_string(k) + " has no name";
    out.stages.emplace_back(names.substr(at, end - at), ms[k]);
    at = end + 1;
  }
  return "";
}

}  // namespace cellphys::server
