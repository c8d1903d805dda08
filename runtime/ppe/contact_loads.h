// What each contact carries under gravity: a body's weight and everything resting on it pass
// down through the contacts that hold it up, top to bottom, so a light box under a heavy one
// (or at the foot of a stack) gets contacts stiff enough for the weight above it. Computed
// from this step's contacts alone: no feedback from how far a contact sank, which, tried
// first, made a pile's contacts stiffen and soften in turn until it was thrown apart.
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "runtime/ppe/body_records.h"

namespace cellphys::ppe {

struct WorldSettings;

/// carry_loads' buffers, kept between steps so a warm step allocates nothing.
/// The per-body arrays are set for the bodies a contact or joint names alone and zeroed
/// again after, so a step pays for what touches, not for every body of the world.
struct LoadScratch {
  std::vector<int64_t> upper;         // per contact: the body it holds up (-1: none)
  std::vector<double> share;          // per contact: how squarely (|n . down|)
  std::vector<uint32_t> involved;     // the bodies named, in the order first named
  std::vector<uint8_t> named;         // per body: in `involved`
  std::vector<double> support;        // per body: the sum of its supports' shares
  std::vector<std::pair<uint32_t, uint32_t>> joints;  // (upper, lower), both dynamic
  std::vector<uint8_t> held;          // per body: jointed to what cannot move
  std::vector<uint32_t> below;        // per body: the joints it hands its weight down
  std::vector<uint8_t> linked;        // per body: a dynamic body rests on it, or it on one
  std::vector<uint32_t> order;        // bodies that pass weight on: those alone, then top to bottom
  std::vector<std::pair<double, uint32_t>> ranked;  // the same with their heights, to sort
  std::vector<double> weight;         // per body: mass pressing on its supports (kg)
  std::vector<size_t> by_upper;       // contacts by the body they hold up
  std::vector<size_t> first_of;       // per body: its first entry in by_upper
  std::vector<uint32_t> count;        // per body: its entries in by_upper
};

/// Sets each contact's load: the mass whose soft spring, at the contact frequency, sinks by
/// contact_load_depth under the weight the contact carries (0 without gravity). A resting body's
/// weight splits over its contacts below it and its joints to bodies below it.
void carry_loads(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const WorldSettings& s,
                 std::vector<WorldContact>& contacts, LoadScratch& scratch);

/// How much gravity alone closes a contact of normal n (from a to b) in a step (m/s, 0 or less):
/// the upper body falls onto what holds it. Against static geometry the fall is signed (a ball
/// thrown up at a ceiling falls away from it); between two bodies the lower one is taken to rest
/// on something, so the upper falls onto it. The contact acts in a step only if its gap closes
/// by the step's end with this fall (codegen/descriptors/forces/contact.yaml).
float gravity_fall(const float n[3], bool against_static, const WorldSettings& s);

}  // namespace cellphys::ppe
