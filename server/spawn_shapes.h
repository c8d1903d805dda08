// The shapes a client can spawn that a scene may lack. A viewer offers a box and a sphere in
// every world, and a spawn command names a shape of the world's dictionary, which no command
// grows (the join sends it once); so `cellphys serve` appends a sphere and a box of 0.25 m
// (radius, half side) to a world that has none of that type before it makes the room. Scene
// shapes keep their indices; bodies and state hashes are unchanged.
#pragma once
#include "runtime/ppe/shapes.h"

namespace cellphys::server {

inline constexpr float kSpawnShapeSize = 0.25f;  // m: the sphere's radius, the box's half side

/// Appends a sphere and a box of kSpawnShapeSize to `shapes` where it has no shape of that type.
void add_spawn_shapes(ppe::ShapeDictionary& shapes);

}  // namespace cellphys::server
