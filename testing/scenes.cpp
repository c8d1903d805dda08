#include "testing/scenes.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace cellphys::testing {

namespace {

// Uniform in [lo, hi) from the top 24 bits of one mt19937 draw: std::uniform_real_distribution
// is not specified bit for bit, this is.
struct Rng {
  std::mt19937 g;
  explicit Rng(uint32_t seed) : g(seed) {}
  float uniform(float lo, float hi) { return lo + (hi - lo) * float(g() >> 8) * (1.0f / 16777216.0f); }
};

// Rotation by `angle` about the unit axis (ax, ay, az), as w x y z.
void axis_angle(float ax, float ay, float az, float angle, float q[4]) {
  const float s = std::sin(0.5f * angle);
  q[0] = std::cos(0.5f * angle), q[1] = ax * s, q[2] = ay * s, q[3] = az * s;
}

// q = a * b
void quat_mul(const float a[4], const float b[4], float q[4]) {
  q[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  q[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
  q[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
  q[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

void random_small_rotation(Rng& r, float max_angle, float q[4]) {
  float a[3], n2 = 0;
  do {
    for (float& x : a) x = r.uniform(-1, 1);
    n2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
  } while (n2 < 1e-4f || n2 > 1.0f);
  const float n = std::sqrt(n2);
  axis_angle(a[0] / n, a[1] / n, a[2] / n, r.uniform(-max_angle, max_angle), q);
}

void copy3(const float* s, float* d) { d[0] = s[0], d[1] = s[1], d[2] = s[2]; }

std::vector<BodyId> dynamic_ids(const World& w, const std::vector<BodyId>& ids) {
  if (!ids.empty()) return ids;
  std::vector<BodyId> all;
  for (BodyId id : w.bodies())
    if (!w.is_static(id)) all.push_back(id);
  return all;
}

}  // namespace

BodyId ground_plane(World& w, float friction) {
  const float up[3] = {0, 0, 1};
  ppe::BodyDesc d;
  d.shape = w.shapes().add_plane(up, 0.0f);
  d.is_static = true;
  d.friction = friction;
  return w.add_body(d);
}

BodyId add_box(World& w, const float half[3], float mass, const float pos[3], const float q[4], float friction) {
  ppe::BodyDesc d;
  d.shape = w.shapes().add_box(half);
  d.mass = mass;
  copy3(pos, d.state.position);
  if (q) std::copy(q, q + 4, d.state.orientation);
  d.friction = friction;
  return w.add_body(d);
}

BodyId add_sphere(World& w, float r, float mass, const float pos[3], float friction) {
  ppe::BodyDesc d;
  d.shape = w.shapes().add_sphere(r);
  d.mass = mass;
  copy3(pos, d.state.position);
  d.friction = friction;
  return w.add_body(d);
}

std::vector<BodyId> stack(World& w, int n, float half_extent, float gap, float mass, const float base[3],
                          float friction, float stagger) {
  const float half[3] = {half_extent, half_extent, half_extent};
  const float zero[3] = {0, 0, 0};
  if (!base) base = zero;
  ppe::BodyDesc d;
  d.shape = w.shapes().add_box(half);  // one dictionary entry for the whole stack
  d.mass = mass;
  d.friction = friction;
  std::vector<BodyId> ids;
  for (int i = 0; i < n; ++i) {
    const float shift = (i % 2 == 1) ? stagger : -stagger;
    d.state.position[0] = base[0] + shift, d.state.position[1] = base[1] + shift;
    d.state.position[2] = base[2] + gap + half_extent + float(i) * (2 * half_extent + gap);
    ids.push_back(w.add_body(d));
  }
  return ids;
}

namespace {
int bin_columns(int n) { return std::max(4, int(std::ceil(4.0 * std::sqrt(double(n) / 65.0)))); }
}  // namespace

float bin_half_width(int n, float half_extent) {
  // the columns' extent (k - 1) * 2.4 + 2 half-extents, plus a little room: 10 for k = 4
  return (1.2f * float(bin_columns(n) - 1) + 1.4f) * half_extent;
}

std::vector<BodyId> spawned_block(World& w, int k, float spacing) {
  std::vector<BodyId> boxes;
  const float step = 2 * 0.3f * spacing;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j)
      for (int l = 0; l < k; ++l) {
        const int n = (i * k + j) * k + l;
        const float half = 0.2f + 0.05f * float(n % 3), mass = 1.0f + 4.0f * float(n % 4);
        const float h[3] = {half, half * 0.8f, half};
        const float p[3] = {step * float(i) + 0.01f * float(n % 5), step * float(j), 0.3f + step * float(l)};
        boxes.push_back(add_box(w, h, mass, p));
      }
  return boxes;
}

std::vector<BodyId> pile_in_bin(World& w, int n, float half_extent, uint32_t seed, float mass) {
  Rng r(seed);
  ground_plane(w, 0.5f);
  const int k = bin_columns(n);
  const float hb = bin_half_width(n, half_extent);  // inside half-width
  const float wall_t = half_extent;                 // wall half-thickness
  const float wall_h = 4.0f * half_extent;          // wall half-height: walls 8 half-extents tall
  const float half[3] = {half_extent, half_extent, half_extent};
  ppe::BodyDesc box;
  box.shape = w.shapes().add_box(half);
  box.mass = mass;
  box.friction = 0.5f;
  const float spacing = 2.4f * half_extent, layer = 2.6f * half_extent;
  std::vector<BodyId> ids;
  for (int i = 0; i < n; ++i) {
    const int col = i % (k * k), lay = i / (k * k);
    const float jx = r.uniform(-0.1f, 0.1f) * half_extent, jy = r.uniform(-0.1f, 0.1f) * half_extent;
    box.state.position[0] = (float(col % k) - 0.5f * float(k - 1)) * spacing + jx;
    box.state.position[1] = (float(col / k) - 0.5f * float(k - 1)) * spacing + jy;
    box.state.position[2] = 1.3f * half_extent + float(lay) * layer;
    random_small_rotation(r, 0.15f, box.state.orientation);
    ids.push_back(w.add_body(box));
  }
  // walls: two along x, two along y, standing on the floor, corners closed
  ppe::BodyDesc wall;
  wall.is_static = true;
  wall.friction = 0.5f;
  const float wx[3] = {hb + 2 * wall_t, wall_t, wall_h}, wy[3] = {wall_t, hb, wall_h};
  const uint32_t sx = w.shapes().add_box(wx), sy = w.shapes().add_box(wy);
  for (int s = -1; s <= 1; s += 2) {
    wall.shape = sx;
    wall.state.position[0] = 0, wall.state.position[1] = float(s) * (hb + wall_t), wall.state.position[2] = wall_h;
    w.add_body(wall);
    wall.shape = sy;
    wall.state.position[0] = float(s) * (hb + wall_t), wall.state.position[1] = 0, wall.state.position[2] = wall_h;
    w.add_body(wall);
  }
  return ids;
}

std::vector<BodyId> sparse_world(World& w, int n, float area, uint32_t seed) {
  Rng r(seed);
  ground_plane(w, 0.5f);
  // A few dictionary shapes at unit size, scaled per body (the reference design's shape index + scale).
  ppe::ShapeDictionary& sd = w.shapes();
  const float b0[3] = {1, 1, 1}, b1[3] = {1, 0.7f, 0.5f}, b2[3] = {1, 0.5f, 0.25f};
  const uint32_t boxes[3] = {sd.add_box(b0), sd.add_box(b1), sd.add_box(b2)};
  const uint32_t sphere = sd.add_sphere(1.0f);
  const uint32_t capsules[2] = {sd.add_capsule(0.5f, 0.8f), sd.add_capsule(0.35f, 1.0f)};
  uint32_t hulls[3];
  for (uint32_t& h : hulls) {
    float pts[36];
    for (float& p : pts) p = r.uniform(-1, 1);
    h = sd.add_hull(pts, 12);
  }
  const int cells = std::max(1, int(std::ceil(std::sqrt(double(n)))));
  const float cell = area / float(cells);
  const float jitter = std::max(0.0f, 0.5f * cell - 0.6f);
  std::vector<BodyId> ids;
  for (int k = 0; k < cells * cells && int(ids.size()) < n; ++k) {
    const float cx = -0.5f * area + (float(k % cells) + 0.5f) * cell + r.uniform(-jitter, jitter);
    const float cy = -0.5f * area + (float(k / cells) + 0.5f) * cell + r.uniform(-jitter, jitter);
    const float size = r.uniform(0.15f, 0.4f);
    const float kind = r.uniform(0, 1);
    const bool dropped = r.uniform(0, 1) < 0.5f;
    const float drop = dropped ? r.uniform(0.05f, 0.5f) : 0.0f;
    const float yaw = r.uniform(-3.14159f, 3.14159f);
    ppe::BodyDesc d;
    d.scale = size;
    d.density = r.uniform(400, 900);
    d.friction = 0.5f;
    d.state.position[0] = cx, d.state.position[1] = cy;
    axis_angle(0, 0, 1, yaw, d.state.orientation);
    const bool pair = k % 10 == 5 && int(ids.size()) + 2 <= n;
    if (pair || kind < 0.4f) {
      d.shape = boxes[pair ? 0 : int(r.uniform(0, 2.999f))];
      float lo[3], hi[3];
      sd.local_aabb(d.shape, size, lo, hi);
      d.state.position[2] = (pair ? 0.0f : drop) - lo[2];
      ids.push_back(w.add_body(d));
      if (pair) {  // a smaller box resting on top, turned a little: a two-body island
        const float base_top = hi[2] - lo[2];
        d.scale = 0.8f * size;
        sd.local_aabb(d.shape, d.scale, lo, hi);
        d.state.position[2] = base_top - lo[2];
        axis_angle(0, 0, 1, yaw + 0.3f, d.state.orientation);
        ids.push_back(w.add_body(d));
      }
    } else if (kind < 0.65f) {
      d.shape = sphere;
      d.state.position[2] = drop + size;
      ids.push_back(w.add_body(d));
    } else if (kind < 0.9f) {  // lying on its side: body z turned to horizontal, then yawed
      d.shape = capsules[int(r.uniform(0, 1.999f))];
      float tilt[4], spin[4];
      axis_angle(0, 1, 0, 1.5707963f, tilt);
      axis_angle(0, 0, 1, yaw, spin);
      quat_mul(spin, tilt, d.state.orientation);
      float lo[3], hi[3];
      sd.local_aabb(d.shape, size, lo, hi);
      d.state.position[2] = drop - lo[0];  // radius: the body x extent is the capsule's radius
      ids.push_back(w.add_body(d));
    } else {  // hulls are always dropped a little, at an arbitrary yaw
      d.shape = hulls[int(r.uniform(0, 2.999f))];
      float lo[3], hi[3];
      sd.local_aabb(d.shape, size, lo, hi);
      d.state.position[2] = 0.05f + drop - lo[2];
      ids.push_back(w.add_body(d));
    }
  }
  return ids;
}

Incline incline(World& w, float angle, float friction) {
  Incline in;
  in.normal[0] = std::sin(angle), in.normal[1] = 0, in.normal[2] = std::cos(angle);
  in.downhill[0] = std::cos(angle), in.downhill[1] = 0, in.downhill[2] = -std::sin(angle);
  ppe::BodyDesc d;
  d.shape = w.shapes().add_plane(in.normal, 0.0f);
  d.is_static = true;
  d.friction = friction;
  in.plane = w.add_body(d);
  return in;
}

void point_on_incline(const Incline& in, float along, float height, float out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = along * in.downhill[k] + height * in.normal[k];
}

void incline_orientation(float angle, float q[4]) { axis_angle(0, 1, 0, angle, q); }

std::vector<BodyId> chain(World& w, int links, float mass_ratio, float height, bool pinned) {
  const float r = 0.05f, half_length = 0.2f, gap = 0.05f;
  const float reach = half_length + 0.5f * gap;  // centre to joint point along the link
  ppe::BodyDesc d;
  d.shape = w.shapes().add_capsule(r, half_length - r);
  axis_angle(0, 1, 0, 1.5707963f, d.state.orientation);  // body z along world +x
  std::vector<BodyId> ids;
  for (int i = 0; i < links; ++i) {
    d.mass = (i % 2 == 0) ? 1.0f : mass_ratio;
    d.state.position[0] = reach + float(i) * 2.0f * reach, d.state.position[1] = 0, d.state.position[2] = height;
    ids.push_back(w.add_body(d));
  }
  // Stiff joints: 1e5 N/m per kg of the heavier link keeps stretch ~ g m_total / k small; damping
  // near critical for the lighter link.
  const float heavy = std::max(1.0f, mass_ratio), light = std::min(1.0f, mass_ratio);
  const float k = 1e5f * heavy, c = 2.0f * std::sqrt(k * light);
  if (pinned)
    w.add_force("point_to_point", ids[0], ppe::kWorldBody,
                {{"point_a", {0, 0, -reach}}, {"point_b", {0, 0, height}}, {"stiffness", {k}}, {"damping", {c}}});
  for (int i = 0; i + 1 < links; ++i)
    w.add_force("point_to_point", ids[i], ids[i + 1],
                {{"point_a", {0, 0, reach}}, {"point_b", {0, 0, -reach}}, {"stiffness", {k}}, {"damping", {c}}});
  return ids;
}

float max_speed(const World& w, const std::vector<BodyId>& ids) {
  float m = 0;
  for (BodyId id : dynamic_ids(w, ids)) {
    const ppe::BodyState s = w.state(id);
    m = std::max(m, std::sqrt(s.velocity[0] * s.velocity[0] + s.velocity[1] * s.velocity[1] + s.velocity[2] * s.velocity[2]));
  }
  return m;
}

float max_angular_speed(const World& w, const std::vector<BodyId>& ids) {
  float m = 0;
  for (BodyId id : dynamic_ids(w, ids)) {
    const ppe::BodyState s = w.state(id);
    const float* a = s.angular_velocity;
    m = std::max(m, std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]));
  }
  return m;
}

int count_asleep(const World& w, const std::vector<BodyId>& ids) {
  int c = 0;
  for (BodyId id : ids) c += w.is_awake(id) ? 0 : 1;
  return c;
}

}  // namespace cellphys::testing
