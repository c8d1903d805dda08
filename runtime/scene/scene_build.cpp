// A SceneDesc into a ppe::World. The World validates everything again (it refuses bad input
// with WorldError / ShapeError); its refusals come back with the path of the scene entry.
#include <map>

#include "runtime/scene/scene.h"

namespace cellphys::scene {

namespace {
std::string at(const char* list, size_t i) { return std::string(list) + "[" + std::to_string(i) + "]"; }
}  // namespace

BuiltScene build_world(const SceneDesc& scene) {
  const std::string& file = scene.source.empty() ? std::string("scene") : scene.source;
  BuiltScene out;
  try {
    out.world = std::make_unique<ppe::World>(scene.settings);
  } catch (const std::invalid_argument& e) {
    throw SceneError(file, "settings", e.what());
  }
  ppe::World& w = *out.world;

  std::map<std::string, uint32_t> shapes;
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const ShapeSpec& s = scene.shapes[i];
    if (shapes.count(s.name)) throw SceneError(file, at("shapes", i) + ".name", "a shape named '" + s.name + "' already exists");
    uint32_t index = 0;
    try {
      switch (s.type) {
        case spu::ShapeType::sphere: index = w.shapes().add_sphere(s.radius); break;
        case spu::ShapeType::box: index = w.shapes().add_box(s.half_extents); break;
        case spu::ShapeType::capsule: index = w.shapes().add_capsule(s.radius, s.half_height); break;
        case spu::ShapeType::hull:
          if (s.points.size() % 3 != 0) throw ppe::ShapeError("hull: points must be x y z triples");
          index = w.shapes().add_hull(s.points.data(), static_cast<int>(s.points.size() / 3));
          break;
        case spu::ShapeType::plane: index = w.shapes().add_plane(s.normal, s.offset); break;
        case spu::ShapeType::mesh:
          index = w.shapes().add_mesh(s.vertices.data(), static_cast<int>(s.vertices.size() / 3), s.triangles.data(),
                                      static_cast<int>(s.triangles.size() / 3));
          break;
        case spu::ShapeType::compound: {
          std::vector<ppe::CompoundPart> parts(s.parts.size());
          for (size_t k = 0; k < s.parts.size(); ++k) {
            const auto named = shapes.find(s.parts[k].shape);
            if (named == shapes.end())
              throw SceneError(file, at("shapes", i) + ".parts[" + std::to_string(k) + "].shape",
                               "no shape named '" + s.parts[k].shape + "' before this one");
            parts[k].shape = named->second;
            std::copy(s.parts[k].position, s.parts[k].position + 3, parts[k].position);
            std::copy(s.parts[k].orientation, s.parts[k].orientation + 4, parts[k].orientation);
            parts[k].scale = s.parts[k].scale;
          }
          index = w.shapes().add_compound(parts.data(), static_cast<int>(parts.size()));
          break;
        }
        case spu::ShapeType::height_field:
          if (s.heights.size() != size_t(s.rows) * size_t(s.columns))
            throw ppe::ShapeError("height_field: heights must be rows x columns");
          index = w.shapes().add_height_field(s.rows, s.columns, s.spacing, s.heights.data());
          break;
      }
    } catch (const std::invalid_argument& e) {  // ShapeError
      throw SceneError(file, at("shapes", i), e.what());
    }
    if (spu::is_triangle_surface(s.type))
      if (const int dropped = w.shapes().surface_input(index).dropped_triangles)
        out.warnings.push_back(file + ": " + at("shapes", i) + ": " + std::to_string(dropped) +
                               " triangle(s) with no area left out");
    shapes[s.name] = index;
  }

  std::map<std::string, ppe::BodyId> ids;
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const BodySpec& b = scene.bodies[i];
    const std::string p = at("bodies", i);
    if (b.id.empty() || b.id == kWorld) throw SceneError(file, p + ".id", "a body needs an id other than 'world'");
    if (ids.count(b.id)) throw SceneError(file, p + ".id", "a body with id '" + b.id + "' already exists");
    const auto shape = shapes.find(b.shape);
    if (shape == shapes.end()) throw SceneError(file, p + ".shape", "unknown shape '" + b.shape + "'");
    ppe::BodyDesc d;
    d.shape = shape->second;
    d.scale = b.scale;
    d.mass = b.mass;
    d.density = b.density;
    d.has_inertia = b.has_inertia;
    std::copy(b.inertia, b.inertia + 6, d.inertia);
    d.state = b.state;
    d.friction = b.friction;
    d.linear_damping = b.linear_damping;
    d.angular_damping = b.angular_damping;
    d.is_static = b.is_static;
    d.sensor = b.sensor;
    try {
      const ppe::BodyId id = w.add_body(d);
      ids[b.id] = id;
      out.bodies.push_back(id);
    } catch (const std::invalid_argument& e) {  // WorldError, ShapeError
      throw SceneError(file, p, e.what());
    }
    for (const std::string& warning : w.warnings()) out.warnings.push_back(file + ": " + p + ": " + warning);
  }

  for (size_t i = 0; i < scene.forces.size(); ++i) {
    const ForceSpec& f = scene.forces[i];
    const std::string p = at("forces", i);
    const auto a = ids.find(f.a);
    if (a == ids.end()) throw SceneError(file, p + ".a", "no body with id '" + f.a + "'");
    ppe::BodyId b = ppe::kWorldBody;
    if (f.b != kWorld) {
      const auto it = ids.find(f.b);
      if (it == ids.end()) throw SceneError(file, p + ".b", "no body with id '" + f.b + "'");
      b = it->second;
    }
    try {
      out.forces.push_back(w.add_force(f.type, a->second, b, f.params));
    } catch (const std::invalid_argument& e) {
      throw SceneError(file, p, e.what());
    }
  }
  return out;
}

}  // namespace cellphys::scene
