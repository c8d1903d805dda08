// The client protocol of `cellphys serve` (docs/protocol.md): every message's layout, declared
// once here. A WebSocket binary message is one protocol message: a Header (length, type,
// version) then the type's fixed part, then, for some types, variable-length arrays described
// by counts in the fixed part. All fields are little-endian and IEEE floats; the structs are
// laid out with no implicit padding (the static_asserts check every size and offset), so an
// encoder memcpy's them and a decoder memcpy's them back out of the bytes.
//
// The generator's struct descriptors (codegen/descriptors/structs) cannot declare these: they
// have 32-bit fields only, and the quantised body needs 16-bit ones; and they feed the
// runtime's generated layouts, which know nothing of clients.
#pragma once
#include <cstddef>
#include <cstdint>

namespace cellphys::server::protocol {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the protocol's structs are its little-endian bytes");

inline constexpr uint16_t kVersion = 1;
// Additions that keep every revision-1 message's layout, announced in Join::revision: 2 adds the
// subscribe flag kSubscribeDebug and the debug message; 3 the subscribe flag kSubscribeStages
// and the stages message, and the debug message's cut couplings (in what was its reserved field);
// 4 the shape types mesh, height_field and compound, with data after their ShapeRecord; 5 the
// set_speed command (a server that announces less refuses it as no command).
inline constexpr uint32_t kRevision = 5;

/// The revision a client must read to read a dictionary holding a shape of this type: a client
/// of revision 3 or less reads data after a hull's ShapeRecord only, so it would take a mesh's,
/// a height field's or a compound's for the next record. The server tells such a client so
/// (docs/protocol.md, "Revisions") rather than send it a join it would misread.
constexpr uint32_t shape_revision(uint32_t type) { return type >= 5 ? 4u : 1u; }

enum class Type : uint16_t {
  // server -> client
  join = 1,    // the world: shape dictionary and every body in the client's interest
  tick = 2,    // one published state: bodies entered, moved and gone, and the step's statistics
  ack = 3,     // a command applied
  error = 4,   // a command refused, or a message that could not be read
  status = 5,  // the world paused, resumed, failed or reset
  debug = 6,   // revision 2: after a tick, to clients subscribed with kSubscribeDebug: islands and contacts
  stages = 7,  // revision 3: after a tick, to clients subscribed with kSubscribeStages: ms per stage of the step
  // client -> server
  subscribe = 32,  // interest region and precision
  spawn = 33,
  remove = 34,
  impulse = 35,
  drag_start = 36,
  drag_move = 37,
  drag_release = 38,
  pause = 39,
  resume = 40,
  step_once = 41,
  reset = 42,
  set_speed = 43,  // revision 5: the pace of the world's steps against real time
};

struct Header {
  uint32_t length;  // bytes of the whole message, this header included
  uint16_t type;    // Type
  uint16_t version; // kVersion
};
static_assert(sizeof(Header) == 8);

// ---- server -> client ----

// Body flags.
inline constexpr uint32_t kBodyAwake = 1u;
inline constexpr uint32_t kBodyStatic = 2u;
inline constexpr uint32_t kBodyUnbounded = 4u;  // a plane: in every region

// Join flags.
inline constexpr uint32_t kJoinCanCommand = 1u;  // the connection gave the server's token

// A body with its shape reference: in a join, and in a tick's `entered` list.
struct BodyFull {
  uint32_t id;
  uint32_t shape;  // index into the join's shape dictionary
  float scale;
  uint32_t flags;  // kBodyAwake, kBodyStatic, kBodyUnbounded
  float position[3];
  float orientation[4];  // w x y z
  float velocity[3];
  float angular_velocity[3];
};
static_assert(sizeof(BodyFull) == 68);
static_assert(offsetof(BodyFull, position) == 16 && offsetof(BodyFull, angular_velocity) == 56);

// A moved body at full precision: the node-to-dispatcher wire table's 13 floats and the id.
struct BodyMoved {
  uint32_t id;
  float position[3];
  float orientation[4];
  float velocity[3];
  float angular_velocity[3];
};
static_assert(sizeof(BodyMoved) == 56);

// A moved body quantised (docs/protocol.md, "Quantised state"): each position, velocity and
// angular velocity component a 16-bit step of the tick's QuantFrame; the orientation as its
// three smallest components at 10 bits each plus the index of the largest in the top 2 bits.
struct BodyMovedQ {
  uint32_t id;
  uint32_t orientation;  // bits 30..31 largest component (0 w, 1 x, 2 y, 3 z); 0..9, 10..19, 20..29 the others in order
  int16_t position[3];   // origin + position_step * p
  int16_t velocity[3];   // velocity_step * v
  int16_t angular_velocity[3];  // angular_step * w
  uint16_t reserved;
};
static_assert(sizeof(BodyMovedQ) == 28);
static_assert(offsetof(BodyMovedQ, position) == 8 && offsetof(BodyMovedQ, angular_velocity) == 20);

struct Join {
  Header header;
  uint32_t epoch;  // incremented at every reset: a new join follows each
  uint32_t flags;  // kJoinCanCommand
  uint64_t step;
  float dt;        // s per step
  float tick_hz;   // steps per real second the server aims at (0: as fast as it can)
  uint32_t num_shapes;
  uint32_t num_bodies;
  uint32_t name_bytes;  // the world's name, UTF-8, padded with zeros to a multiple of 4
  uint32_t revision;    // kRevision (0 from a revision-1 server)
  // then: name | num_shapes x [ShapeRecord | vertex and face data, or compound parts] | num_bodies x BodyFull
};
static_assert(sizeof(Join) == 48);

// One entry of the shape dictionary. A hull's ShapeRecord is followed by its vertices
// (num_vertices x 3 floats), face_start (num_faces + 1 uint32) and face_vertices
// (num_face_vertices uint32: each face's vertex loop, counter-clockwise seen from outside).
// A mesh or a height field is followed by the same three arrays, its triangles the faces
// (face_start 0, 3, 6, ...; each counter-clockwise seen from the surface's front), so a client
// draws it as it draws a hull; a height field comes as the triangles its grid was made into.
// A compound's is followed by its parts: num_vertices x CompoundPartRecord (revision 4; the
// record's layout is unchanged, its count field reused).
struct ShapeRecord {
  uint32_t type;  // spu::ShapeType: 0 sphere, 1 capsule, 2 box, 3 hull, 4 plane, 5 mesh, 6 height_field,
                  // 7 compound (as shape_type_name)
  uint32_t num_vertices;  // hulls, meshes, height fields: vertices | compound: parts (1 to 64) | 0 otherwise
  uint32_t num_faces, num_face_vertices;  // hulls, meshes, height fields; 0 otherwise
  float params[8];  // sphere: radius | capsule: radius, half_height (on body z) | box: half extents |
                    // plane: normal x y z, offset (n.x <= offset solid) | hull, mesh, height field, compound: unused
};
static_assert(sizeof(ShapeRecord) == 48);

// One part of a compound (revision 4), as the world's dictionary holds it
// (ppe::ShapeDictionary::compound_parts): a shape of the dictionary at a pose in the compound's
// frame, which is centred on the compound's centre of mass, so a part's world pose is
// spu::part_pose(body pose, part): position + R(body) (body scale * part position), orientation
// body * part, scale body * part.
struct CompoundPartRecord {
  uint32_t shape;        // an earlier ShapeRecord of the same join: sphere, capsule, box or hull
  float position[3];
  float orientation[4];  // w x y z, unit
  float scale;
};
static_assert(sizeof(CompoundPartRecord) == 36);
static_assert(offsetof(CompoundPartRecord, orientation) == 16 && offsetof(CompoundPartRecord, scale) == 32);

// Tick flags.
inline constexpr uint32_t kTickQuantised = 1u;  // `moved` holds BodyMovedQ, not BodyMoved
inline constexpr uint32_t kTickPaused = 2u;

// The step's statistics (ppe::StepStats, in part).
struct TickStats {
  float step_ms;  // wall time of the step
  uint32_t active_bodies, sleeping_bodies, contacts, islands, solver_iterations, failed_islands, step_halvings;
};
static_assert(sizeof(TickStats) == 32);

// The scales of a quantised tick (zero when not quantised).
struct QuantFrame {
  float origin[3];
  float position_step;  // m
  float velocity_step;  // m/s
  float angular_step;   // rad/s
};
static_assert(sizeof(QuantFrame) == 24);

struct Tick {
  Header header;
  uint64_t step;
  uint32_t epoch;
  uint32_t flags;    // kTickQuantised, kTickPaused
  uint32_t skipped;  // states published since the last one sent that this client did not get (it was behind)
  uint32_t num_entered, num_moved, num_gone;
  TickStats stats;
  QuantFrame quant;
  // then: num_entered x BodyFull | num_moved x (BodyMoved or BodyMovedQ) | num_gone x uint32 id
};
static_assert(sizeof(Tick) == 96);
static_assert(offsetof(Tick, stats) == 40 && offsetof(Tick, quant) == 72);

// What the solver did in the tick's step, for overlays (revision 2). The whole world, whatever
// the client's region.
struct Debug {
  Header header;
  uint64_t step;
  uint32_t epoch;
  uint32_t num_bodies;    // every dynamic body
  uint32_t num_contacts;  // contacts of awake bodies in the step and those kept by sleeping groups
  uint32_t num_cuts;      // revision 3 (0 before): couplings the step's decoupling cut
  // then: num_bodies x DebugBody | num_contacts x DebugContact | num_cuts x DebugCut
};
static_assert(sizeof(Debug) == 32);

inline constexpr uint32_t kNoIsland = 0xFFFFFFFFu;
inline constexpr uint32_t kIslandDecoupled = 1u;  // DebugBody::flags: its island was cut in parts

struct DebugBody {
  uint32_t id;
  uint32_t island;  // index of its island in the step, kNoIsland when asleep
  float mass;       // kg
  uint32_t flags;   // kIslandDecoupled
};
static_assert(sizeof(DebugBody) == 16);

struct DebugContact {
  uint32_t a, b;      // body ids; b = 0xFFFFFFFF: static geometry
  float point[3];     // world
  float normal[3];    // from a to b
  float depth;        // m
  float force;        // N, the normal force the step applied there (ppe::DebugContact)
};
static_assert(sizeof(DebugContact) == 40);

inline constexpr uint32_t kNoForce = 0xFFFFFFFFu;

// A coupling the decoupling stage cut (revision 3): a contact or force between bodies of one
// island that its cut put in different parts, each part holding the other body as a ghost.
struct DebugCut {
  uint32_t a, b;     // body ids (both dynamic, of the same island)
  uint32_t force;    // the force's id, or kNoForce for a contact
  uint32_t island;   // as DebugBody::island numbers them
  float point[3];    // a contact's point (world); zero for a force
  uint32_t reserved;
};
static_assert(sizeof(DebugCut) == 32);

// The wall time of each stage of the tick's step (revision 3), as ppe::StageTimes names them
// (runtime/ppe/step_stats.h): the list is the server's, so a client draws whatever stages it
// names. The one named "total" is the whole step; the others are its parts.
struct Stages {
  Header header;
  uint64_t step;
  uint32_t epoch;
  uint32_t num_stages;
  uint32_t names_bytes;  // the names section, padded
  uint32_t reserved;
  // then: num_stages x f32 ms | names: num_stages UTF-8 names, each ended by a zero byte, the
  // whole padded with zeros to names_bytes (a multiple of 4)
};
static_assert(sizeof(Stages) == 32);

struct Ack {
  Header header;
  uint32_t seq;           // the command's
  uint16_t command_type;  // Type
  uint16_t reserved;
  uint64_t step;          // the world's step counter when it was applied (before the next step)
  uint32_t result;        // spawn: the new body's id; drag_start: the drag's id; else 0
  uint32_t reserved2;
};
static_assert(sizeof(Ack) == 32);

enum class ErrorCode : uint16_t {
  malformed = 1,     // not a protocol message (length, type, version)
  invalid = 2,       // a field is wrong: `field` names it, `reason` says why
  unauthorized = 3,  // a command on a connection that gave no token
  rate_limited = 4,  // too many commands: refused, the connection stays (docs/protocol.md)
  world_failed = 5,  // the world failed and accepts only reset
};

struct Error {
  Header header;
  uint32_t seq;           // the command's (0 for a message that could not be read)
  uint16_t command_type;  // Type of the refused message (0 if unknown)
  uint16_t code;          // ErrorCode
  uint16_t field_bytes, reason_bytes;
  uint32_t reserved;
  // then: field (UTF-8, e.g. "spawn.orientation"), reason, zero-padded to a multiple of 4
};
static_assert(sizeof(Error) == 24);

enum class WorldState : uint32_t { running = 0, paused = 1, failed = 2 };

struct Status {
  Header header;
  uint32_t state;  // WorldState
  uint32_t text_bytes;
  uint64_t step;
  // then: text (a failure's message), zero-padded to a multiple of 4
};
static_assert(sizeof(Status) == 24);

// ---- client -> server ----

// Subscribe flags.
inline constexpr uint32_t kSubscribeQuantised = 1u;
inline constexpr uint32_t kSubscribeRegion = 2u;  // only bodies whose centre is in [min, max]
inline constexpr uint32_t kSubscribeDebug = 4u;   // revision 2: a debug message after every tick
inline constexpr uint32_t kSubscribeStages = 8u;  // revision 3: a stages message after every tick

struct Subscribe {
  Header header;
  uint32_t flags;
  uint32_t reserved;
  float min[3], max[3];
};
static_assert(sizeof(Subscribe) == 40);

// Every command opens with the header and a sequence number the client picks; its Ack or
// Error carries it back.
struct CommandHead {
  Header header;
  uint32_t seq;
};
static_assert(sizeof(CommandHead) == 12);

struct Spawn {
  Header header;
  uint32_t seq;
  uint32_t shape;  // index into the shape dictionary (not a plane)
  float scale;
  float mass;      // kg
  float friction;
  float position[3];
  float orientation[4];  // w x y z, unit
  float velocity[3];
  float angular_velocity[3];
};
static_assert(sizeof(Spawn) == 80);

struct Remove {
  Header header;
  uint32_t seq;
  uint32_t body;
};
static_assert(sizeof(Remove) == 16);

struct Impulse {
  Header header;
  uint32_t seq;
  uint32_t body;
  float impulse[3];  // N s, world frame
  float point[3];    // world frame
};
static_assert(sizeof(Impulse) == 40);

// A drag: a zero-length spring-damper (the point_to_point force) from a point of the body to a
// target the client moves, until released.
struct DragStart {
  Header header;
  uint32_t seq;
  uint32_t body;
  float point[3];   // the grabbed point, world frame (held as the body point under it now)
  float target[3];  // world frame
  float stiffness;  // N/m; 0: the body's mass times (2 pi 2 Hz)^2
  float damping;    // N s/m; 0: critical for that stiffness
};
static_assert(sizeof(DragStart) == 48);

struct DragMove {
  Header header;
  uint32_t seq;
  uint32_t drag;  // the id the drag_start's Ack gave
  float target[3];
};
static_assert(sizeof(DragMove) == 28);

struct DragRelease {
  Header header;
  uint32_t seq;
  uint32_t drag;
};
static_assert(sizeof(DragRelease) == 16);

// pause, resume, step_once and reset: no fields but the sequence number.
struct Control {
  Header header;
  uint32_t seq;
  uint32_t reserved;
};
static_assert(sizeof(Control) == 16);

// set_speed (revision 5): the room steps at speed times its tick rate (slow motion below 1),
// each step still of the world's dt; the physics is unchanged. No effect under `--fast`.
inline constexpr float kMinSpeed = 0.05f, kMaxSpeed = 8.0f;
struct SetSpeed {
  Header header;
  uint32_t seq;
  float speed;  // [kMinSpeed, kMaxSpeed]
};
static_assert(sizeof(SetSpeed) == 16);

/// The fixed size of a client message of this type; 0 for a type clients do not send.
constexpr size_t client_message_size(uint16_t type) {
  switch (static_cast<Type>(type)) {
    case Type::subscribe: return sizeof(Subscribe);
    case Type::spawn: return sizeof(Spawn);
    case Type::remove: return sizeof(Remove);
    case Type::impulse: return sizeof(Impulse);
    case Type::drag_start: return sizeof(DragStart);
    case Type::drag_move: return sizeof(DragMove);
    case Type::drag_release: return sizeof(DragRelease);
    case Type::pause:
    case Type::resume:
    case Type::step_once:
    case Type::reset: return sizeof(Control);
    case Type::set_speed: return sizeof(SetSpeed);
    default: return 0;
  }
}

/// The name of a message type, for fields in errors ("spawn.scale") and logs; "" if unknown.
const char* type_name(uint16_t type);

}  // namespace cellphys::server::protocol
