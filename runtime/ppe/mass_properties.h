// Volume, mass, centre of mass and inertia of dictionary shapes at a uniform scale, from a
// density or from a total mass. Computed in double; exact closed forms for spheres, boxes
// and capsules, exact polyhedral integration for hulls.
#pragma once
#include <cstdint>

#include "runtime/ppe/shapes.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

struct MassProperties {
  double volume = 0.0;
  double mass = 0.0;
  /// Body coordinates: zero for spheres, capsules and boxes, and (up to float rounding of the
  /// stored vertices) for hulls, which the dictionary re-centres.
  double center_of_mass[3] = {};
  /// About the centre of mass in body axes: Ixx Iyy Izz Ixy Ixz Iyz, with the products
  /// carrying the tensor's sign (Ixy = -integral of rho x y dV).
  double inertia[6] = {};
};

/// Throw ShapeError for non-positive or non-finite scale/density/mass, and for planes.
MassProperties mass_properties_from_density(const spu::ShapeView& shape, float scale, float density);
/// The density is chosen so the shape weighs mass.
MassProperties mass_properties_from_mass(const spu::ShapeView& shape, float scale, float mass);
MassProperties mass_properties_from_density(const ShapeDictionary& shapes, uint32_t shape, float scale,
                                            float density);
MassProperties mass_properties_from_mass(const ShapeDictionary& shapes, uint32_t shape, float scale, float mass);

/// A closed polyhedron at unit density (mass = volume), by tetrahedra from its vertex mean;
/// inertia about its own centroid. Faces must be outward (ccw loops).
MassProperties polyhedron_mass_properties(const spu::HullView& hull);

}  // namespace cellphys::ppe
