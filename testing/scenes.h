// Scenes shared by the world tests and benchmarks: builders that add shapes and bodies to a
// ppe::World and return what they made. Every builder is deterministic (a seed, where there
// is randomness, drives a fixed std::mt19937 and hand-rolled uniform draws, so the same seed
// gives the same scene on every standard library).
//
// Conventions: gravity is -z, the ground is the plane z = 0 (solid below), lengths in metres,
// masses in kilograms. Boxes default to 1 kg, as the reference group
// (testing/reference_island.h).
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/world.h"

namespace cellphys::testing {

using ppe::BodyId;
using ppe::World;

/// A static plane z = 0 (solid below) with the given friction coefficient.
BodyId ground_plane(World& w, float friction = 0.5f);

/// n boxes (one dictionary box) of half-extent `half_extent` and `mass` kg stacked along z,
/// the lowest face at z = base[2] + gap and `gap` between consecutive boxes (0 = each resting
/// exactly on the one below, touching, no overlap), centred on (base[0], base[1]). `stagger`
/// shifts odd boxes by +stagger and even ones by -stagger in x and y: a slightly imperfect
/// stack. Bottom first.
std::vector<BodyId> stack(World& w, int n, float half_extent, float gap = 0.0f, float mass = 1.0f,
                          const float base[3] = nullptr, float friction = 0.5f, float stagger = 0.0f);

/// The reference scene: n boxes of half-extent `half_extent` (the reference design's 0.25 m) and
/// `mass` kg (the reference group: 1 kg), dropped with small random rotations (up to
/// 0.15 rad about a random axis) and horizontal jitter (up to 0.1 half-extent) from a k x k grid
/// of columns (2.4 half-extents apart, layers 2.6 half-extents apart, the lowest 0.3
/// half-extent above the floor) into a bin: the ground plane (added here) and 4 static wall
/// boxes 8 half-extents tall. k = 4 for up to 65 boxes and grows as sqrt(n) beyond, so the inside
/// (10 half-extents square for 65 boxes: 2.5 m) keeps piles about 3 layers deep. Returns the n
/// dynamic boxes (the plane and the walls come after them in id order).
std::vector<BodyId> pile_in_bin(World& w, int n, float half_extent = 0.25f, uint32_t seed = 1, float mass = 1.0f);

/// Inside half-width of the bin pile_in_bin builds for n boxes of a half-extent.
float bin_half_width(int n, float half_extent);

/// n bodies on a fresh ground plane (added here), scattered over the square
/// [-area/2, area/2]^2: about 40% boxes, 25% spheres, 25% capsules lying on their side and 10%
/// convex hulls (a random cloud of 12 points), sizes 0.15..0.4 m, density 400..900 kg/m^3.
/// Each body sits in its own jittered grid cell of side area / ceil(sqrt(n)), so cells must be
/// larger than ~1.2 m to keep bodies apart (area >= 1.2 sqrt(n)). About half rest on the ground
/// (touching it), the others are dropped from 0.05..0.5 m (hulls always, at an arbitrary yaw);
/// every tenth cell holds a second box resting on the first (a two-body island). Shapes come
/// from 9 dictionary entries at unit size, scaled per body. Returns the dynamic bodies.
std::vector<BodyId> sparse_world(World& w, int n, float area, uint32_t seed = 1);

/// A k x k x k block of boxes of mixed sizes (half extents 0.2..0.3 m, flattened 0.8 in y) and
/// masses (1..13 kg), on a grid of `spacing` times 0.6 m from 0.3 m up: below 1 they are spawned
/// into each other (no ground: add one). Returns the boxes.
std::vector<BodyId> spawned_block(World& w, int k, float spacing);

/// A static plane through the origin tilted by `angle` (radians) about the y axis: it falls
/// towards +x. Returns the plane and its frame.
struct Incline {
  BodyId plane;
  float normal[3];    // out of the surface
  float downhill[3];  // unit, along the surface, steepest descent
};
Incline incline(World& w, float angle, float friction);
/// A point `along` metres downhill from the origin and `height` above the surface.
void point_on_incline(const Incline& in, float along, float height, float out[3]);
/// The quaternion (w x y z) that turns body z into the incline's normal (for a box that should
/// lie flat on the incline).
void incline_orientation(float angle, float q[4]);

/// A chain: `links` capsules (radius 0.05 m, 0.4 m long) laid out along +x at `height`, each
/// joined to the next by a point_to_point force between points 0.025 m beyond their tips (a
/// 0.05 m gap, so neighbours do not collide), the first pinned to the world at its left end when
/// `pinned`. Link masses alternate between 1 kg and mass_ratio kg (the heavy-light stiffness
/// test). Joint stiffness 1e5 N/m per kg of the heavier link, damping 2 sqrt(k m_light).
/// Returns the links.
std::vector<BodyId> chain(World& w, int links, float mass_ratio = 1.0f, float height = 3.0f, bool pinned = true);

// ---- small helpers for scenes and checks ----

/// A box body (mass in kg) at a position with an orientation (w x y z), default identity; adds
/// its own dictionary box.
BodyId add_box(World& w, const float half[3], float mass, const float pos[3], const float q[4] = nullptr,
               float friction = 0.5f);
/// A sphere body of radius r at pos.
BodyId add_sphere(World& w, float r, float mass, const float pos[3], float friction = 0.5f);

/// Largest linear speed over `ids` (or every dynamic body if ids is empty).
float max_speed(const World& w, const std::vector<BodyId>& ids = {});
/// Largest angular speed over `ids` (or every dynamic body).
float max_angular_speed(const World& w, const std::vector<BodyId>& ids = {});
/// Number of `ids` asleep.
int count_asleep(const World& w, const std::vector<BodyId>& ids);

}  // namespace cellphys::testing
