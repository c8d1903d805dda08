#include "server/spawn_shapes.h"

namespace cellphys::server {

namespace {

bool has(const ppe::ShapeDictionary& shapes, spu::ShapeType t) {
  for (uint32_t i = 0; i < shapes.size(); ++i)
    if (shapes.type(i) == t) return true;
  return false;
}

}  // namespace

void add_spawn_shapes(ppe::ShapeDictionary& shapes) {
  if (!has(shapes, spu::ShapeType::sphere)) shapes.add_sphere(kSpawnShapeSize);
  if (!has(shapes, spu::ShapeType::box)) {
    const float half[3] = {kSpawnShapeSize, kSpawnShapeSize, kSpawnShapeSize};
    shapes.add_box(half);
  }
}

}  // namespace cellphys::server
