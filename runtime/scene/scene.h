// Scene files: a world described as plain data (settings, shapes, bodies, forces), read from
// and written to JSON (docs/scene-format.md), and built into a ppe::World. SceneDesc holds no
// JSON types, so other programs (a benchmark building the same scene in another engine, a
// server loading a level) can consume it with this header alone.
#pragma once
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "runtime/ppe/world.h"
#include "runtime/spu/shape.h"

namespace cellphys::scene {

/// A scene that cannot be read or built. what() is "FILE: PATH: REASON" (PATH is the JSON
/// path of the bad field, e.g. bodies[3].position[1]; empty when the whole file is at fault).
class SceneError : public std::runtime_error {
 public:
  SceneError(std::string file, std::string path, std::string reason);
  const std::string& file() const { return file_; }
  const std::string& path() const { return path_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string file_, path_, reason_;
};

/// A part of a compound shape: a shape named earlier in the file, at a pose in the compound's frame.
struct PartSpec {
  std::string shape;
  float position[3] = {};
  float orientation[4] = {1.0f, 0.0f, 0.0f, 0.0f};
  float scale = 1.0f;
  bool operator==(const PartSpec& o) const;
};

struct ShapeSpec {
  std::string name;
  spu::ShapeType type = spu::ShapeType::sphere;  // by spu::shape_type_name in the file
  float radius = 0.0f;                // sphere, capsule
  float half_extents[3] = {};         // box
  float half_height = 0.0f;           // capsule: core segment -half_height..+half_height on z
  std::vector<float> points;          // hull: x y z per point, re-centred on the centre of mass
  float normal[3] = {0.0f, 0.0f, 1.0f};  // plane: n.x <= offset is solid
  float offset = 0.0f;
  std::vector<float> vertices;        // mesh: x y z per vertex (inline, or read from `obj`)
  std::vector<int32_t> triangles;     // mesh: 3 vertex indices per triangle, counter-clockwise from the front
  std::string obj;                    // mesh: the OBJ file it was read from, as the scene names it ("" inline)
  int32_t rows = 0, columns = 0;      // height field: the grid
  float spacing[2] = {};              // height field: between columns (x) and between rows (y)
  std::vector<float> heights;         // height field: rows x columns, row-major (row i along y)
  std::vector<PartSpec> parts;        // compound: re-centred on their centre of mass when built
};

struct BodySpec {
  std::string id;          // the user's name for the body (an integer id is kept as its text)
  bool id_is_integer = false;
  std::string shape;       // a ShapeSpec name
  float scale = 1.0f;
  float mass = 0.0f;       // kg; a dynamic body has mass or density (not both)
  float density = 0.0f;    // kg/m^3
  bool has_inertia = false;
  float inertia[6] = {};   // Ixx Iyy Izz Ixy Ixz Iyz, body axes
  ppe::BodyState state;    // the file's position, orientation, velocity and angular_velocity
  float friction = 0.5f;
  float linear_damping = 0.0f;   // 1/s
  float angular_damping = 0.0f;  // 1/s
  bool is_static = false;
  bool sensor = false;  // reports overlaps, exerts no force (ppe::BodyDesc::sensor)
};

/// The world side of a force ("b": "world").
inline constexpr const char* kWorld = "world";

struct ForceSpec {
  std::string type;  // a force descriptor's name (gen::kForceTable)
  std::string a;     // body id
  std::string b = kWorld;  // body id or "world"
  ppe::ForceParams params;  // by the descriptor's parameter names, in file order
};

struct SceneDesc {
  std::string source;       // file name (or the name given to parse_scene), for messages
  std::string description;  // one line
  ppe::WorldSettings settings;
  std::vector<ShapeSpec> shapes;
  std::vector<BodySpec> bodies;
  std::vector<ForceSpec> forces;
};

bool operator==(const ppe::WorldSettings& a, const ppe::WorldSettings& b);
bool operator==(const ShapeSpec& a, const ShapeSpec& b);
bool operator==(const BodySpec& a, const BodySpec& b);
bool operator==(const ForceSpec& a, const ForceSpec& b);
/// Field by field, ignoring `source`.
bool operator==(const SceneDesc& a, const SceneDesc& b);
inline bool operator!=(const SceneDesc& a, const SceneDesc& b) { return !(a == b); }

/// Reads and checks a scene file (syntax, names, types, finiteness, references). Throws
/// SceneError naming the file, the JSON path and the reason.
SceneDesc load_scene(const std::string& path);
/// The same on text already in memory; `name` stands for the file in messages.
SceneDesc parse_scene(const std::string& text, const std::string& name);
/// JSON text that parse_scene reads back to an equal SceneDesc (floats round-trip exactly).
std::string write_scene(const SceneDesc& scene);

/// A world built from a scene: World ids of desc.bodies (same order) and of desc.forces.
struct BuiltScene {
  std::unique_ptr<ppe::World> world;
  std::vector<ppe::BodyId> bodies;
  std::vector<ppe::ForceId> forces;
  std::vector<std::string> warnings;  // the World's (e.g. a normalised quaternion), with paths
};
/// Builds the world; the World's own refusals (bad shape, bad mass, ...) come back as
/// SceneError with the path of the offending entry.
BuiltScene build_world(const SceneDesc& scene);

}  // namespace cellphys::scene
