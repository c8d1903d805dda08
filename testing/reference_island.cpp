#include "testing/reference_island.h"

namespace cellphys::testing {

using namespace cellphys::gen;

Rigid_Body_Fields box_body(float m, float hx, float hy, float hz) {
  Rigid_Body_Fields b;
  b.orientation[0] = 1.0f;
  b.mass = m;
  b.inverse_mass = 1.0f / m;
  const float I[3] = {m / 3 * (hy * hy + hz * hz), m / 3 * (hx * hx + hz * hz), m / 3 * (hx * hx + hy * hy)};
  for (int k = 0; k < 3; ++k) {
    b.inertia_body[k] = I[k];
    b.inverse_inertia_body[k] = 1.0f / I[k];
  }
  b.friction = 0.5f;
  b.scale = 1.0f;
  return b;
}

namespace {

constexpr float kHalf = 0.25f, kPen = 0.001f;

// Four contacts at the corners of the rectangle [x0,x1] x [y0,y1] at height z, normal n.
void four_contacts(spu::IslandBuilder& ib, int a, int b, float x0, float x1, float y0, float y1, float z,
                   const float (&n)[3]) {
  for (float x : {x0, x1})
    for (float y : {y0, y1}) {
      Contact_Force_Fields c;
      c.point[0] = x, c.point[1] = y, c.point[2] = z;
      c.normal[0] = n[0], c.normal[1] = n[1], c.normal[2] = n[2];
      c.penetration = kPen;
      c.friction = 0.5f;
      c.body_a = a;
      c.body_b = b;
      Contact_Force packed;
      pack(c, packed);
      ib.add(ForceType::contact, packed);
    }
}

}  // namespace

void build_reference_island(spu::IslandBuilder& ib) {
  const float up[3] = {0, 0, 1}, side[3] = {1, 0, 0};
  const float pitch = 2 * kHalf;
  int bottom[3][11], top_ids[3][11] = {};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 11; ++c) {
      Rigid_Body_Fields b = box_body(1.0f, kHalf, kHalf, kHalf);
      b.position[0] = c * pitch, b.position[1] = r * pitch, b.position[2] = kHalf - kPen;
      bottom[r][c] = ib.add_body(b);
      // the ground is static geometry: world-anchored contacts, body b = -1
      four_contacts(ib, bottom[r][c], -1, b.position[0] - kHalf, b.position[0] + kHalf, b.position[1] - kHalf,
                    b.position[1] + kHalf, 0.0f, up);
    }
  const float z_top = 3 * kHalf - 2 * kPen;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 10; ++c) {  // bridging bottom c and c + 1
      Rigid_Body_Fields b = box_body(1.0f, kHalf, kHalf, kHalf);
      b.position[0] = (c + 0.5f) * pitch, b.position[1] = r * pitch, b.position[2] = z_top;
      const int id = top_ids[r][c] = ib.add_body(b);
      for (int k = 0; k < 2; ++k) {
        const float xc = (c + k) * pitch;
        const float x0 = std::max(xc - kHalf, b.position[0] - kHalf), x1 = std::min(xc + kHalf, b.position[0] + kHalf);
        four_contacts(ib, bottom[r][c + k], id, x0, x1, b.position[1] - kHalf, b.position[1] + kHalf, 2 * kHalf - kPen, up);
      }
    }
  for (int r = 0; r < 2; ++r) {  // two upper boxes resting on one lower box each
    Rigid_Body_Fields b = box_body(1.0f, kHalf, kHalf, kHalf);
    b.position[0] = 10 * pitch, b.position[1] = r * pitch, b.position[2] = z_top + 2 * kHalf;
    const int id = ib.add_body(b);
    four_contacts(ib, top_ids[r][9], id, b.position[0] - kHalf, b.position[0] - kHalf + 0.1f, b.position[1] - kHalf,
                  b.position[1] + kHalf, z_top + kHalf - kPen, up);
  }
  for (int c = 0; c < 5; ++c) {  // side contacts between neighbouring upper boxes of row 2
    const int a = top_ids[2][2 * c], b = top_ids[2][2 * c + 1];
    const float x = (2 * c + 1) * pitch;
    for (float y : {2 * pitch - 0.2f, 2 * pitch + 0.2f})
      for (float z : {z_top - 0.2f, z_top + 0.2f}) {
        Contact_Force_Fields f;
        f.point[0] = x, f.point[1] = y, f.point[2] = z;
        f.normal[0] = side[0], f.normal[1] = side[1], f.normal[2] = side[2];
        f.penetration = kPen;
        f.friction = 0.5f;
        f.body_a = a;
        f.body_b = b;
        Contact_Force packed;
        pack(f, packed);
        ib.add(ForceType::contact, packed);
      }
  }
  ib.add_global(ForceType::gravity);
}

}  // namespace cellphys::testing
