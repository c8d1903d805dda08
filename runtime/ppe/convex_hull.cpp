#include "runtime/ppe/convex_hull.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "runtime/base/vec3.h"

namespace cellphys::ppe {
namespace {

__extension__ typedef __int128 i128;

// Grid coordinates: up to 2^40, so the orientation determinant fits 128 bits exactly.
struct Q3 {
  int64_t x, y, z;
};
constexpr double kGrid = 1099511627776.0;  // 2^40

// Sign of (b-a)x(c-a).(d-a): positive when d is above the triangle abc, ccw seen from above.
int orient(const Q3& a, const Q3& b, const Q3& c, const Q3& d) {
  const int64_t bx = b.x - a.x, by = b.y - a.y, bz = b.z - a.z;
  const int64_t cx = c.x - a.x, cy = c.y - a.y, cz = c.z - a.z;
  const int64_t dx = d.x - a.x, dy = d.y - a.y, dz = d.z - a.z;
  const i128 nx = i128(by) * cz - i128(bz) * cy;
  const i128 ny = i128(bz) * cx - i128(bx) * cz;
  const i128 nz = i128(bx) * cy - i128(by) * cx;
  const i128 det = nx * dx + ny * dy + nz * dz;
  return (det > 0) - (det < 0);
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

[[noreturn]] void fail(const std::string& what) { throw ShapeError("hull: " + what); }
[[noreturn]] void fail_invalid() {
  fail("could not build a valid hull from these points (numerically degenerate input)");
}

struct Tri {
  int v[3];
  int nb[3];  // neighbour across the edge v[k] -> v[k+1]
  Vec3d n;  // approximate plane, only to pick the farthest point
  double d = 0;
  std::vector<int> outside;  // points strictly above (exact test), assigned to this face
  bool alive = true;
};

// Quickhull over exact orientation tests: the visible region from a point strictly outside
// is then exactly a disc, so the horizon is always one simple loop.
class Quickhull {
 public:
  Quickhull(const std::vector<Vec3d>& p, const std::vector<Q3>& q) : P_(p), Q_(q) {}
  /// Hull of the points pts (indices into P), starting from the simplex abcd among them.
  /// May be called again; each run starts afresh.
  void run(const std::vector<int>& pts, int a, int b, int c, int d);
  std::vector<Tri> faces;

 private:
  int above(int f, int p) const {
    const Tri& t = faces[f];
    return orient(Q_[t.v[0]], Q_[t.v[1]], Q_[t.v[2]], Q_[p]);
  }
  int add(int a, int b, int c);
  void assign(int p, int first_face);

  const std::vector<Vec3d>& P_;
  const std::vector<Q3>& Q_;
  std::vector<int> start_;  // per point: the horizon edge starting there, or -1
};

int Quickhull::add(int a, int b, int c) {
  Tri t;
  t.v[0] = a, t.v[1] = b, t.v[2] = c;
  t.nb[0] = t.nb[1] = t.nb[2] = -1;
  const Vec3d n = cross(P_[b] - P_[a], P_[c] - P_[a]);
  const double l = norm(n);
  t.n = l > 0 ? n * (1.0 / l) : Vec3d{};
  t.d = dot(t.n, P_[a]);
  faces.push_back(std::move(t));
  return static_cast<int>(faces.size()) - 1;
}

void Quickhull::assign(int p, int first_face) {
  for (int f = first_face; f < static_cast<int>(faces.size()); ++f)
    if (above(f, p) > 0) {
      faces[f].outside.push_back(p);
      return;
    }
}

void Quickhull::run(const std::vector<int>& pts, int a, int b, int c, int d) {
  faces.clear();
  start_.resize(P_.size(), -1);
  if (orient(Q_[a], Q_[b], Q_[c], Q_[d]) > 0) std::swap(b, c);  // d below abc
  add(a, b, c), add(a, d, b), add(b, d, c), add(c, d, a);
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 4; ++j)
        for (int m = 0; m < 3; ++m)
          if (j != i && faces[j].v[m] == faces[i].v[(k + 1) % 3] && faces[j].v[(m + 1) % 3] == faces[i].v[k])
            faces[i].nb[k] = j;
  for (int p : pts)
    if (p != a && p != b && p != c && p != d) assign(p, 0);

  struct Edge {
    int u, w, g;  // edge u -> w of a visible face, g the hidden face across it
  };
  std::vector<int> visible, stack, loop, vis, hid;
  std::vector<int>& start = start_;
  std::vector<Edge> horizon;
  int stamp = 0;
  for (size_t fi = 0; fi < faces.size(); ++fi) {
    if (!faces[fi].alive || faces[fi].outside.empty()) continue;
    int eye = -1;
    double best = -std::numeric_limits<double>::infinity();
    for (int p : faces[fi].outside) {
      const double dist = dot(faces[fi].n, P_[p]) - faces[fi].d;
      if (dist > best) best = dist, eye = p;
    }
    ++stamp;
    vis.resize(faces.size(), 0), hid.resize(faces.size(), 0);
    visible.assign(1, static_cast<int>(fi));
    stack.assign(1, static_cast<int>(fi));
    horizon.clear();
    vis[fi] = stamp;
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      for (int k = 0; k < 3; ++k) {
        const int g = faces[f].nb[k];
        if (vis[g] == stamp) continue;
        if (hid[g] != stamp) {
          if (above(g, eye) > 0) {
            vis[g] = stamp;
            visible.push_back(g);
            stack.push_back(g);
            continue;
          }
          hid[g] = stamp;
        }
        horizon.push_back({faces[f].v[k], faces[f].v[(k + 1) % 3], g});
      }
    }
    // Chain the horizon edges into their loop.
    for (size_t h = 0; h < horizon.size(); ++h) start[horizon[h].u] = static_cast<int>(h);
    loop.clear();
    for (int h = 0;;) {
      loop.push_back(h);
      h = start[horizon[h].w];
      if (h <= 0 || loop.size() > horizon.size()) {
        if (h != 0) throw std::logic_error("hull: horizon is not a simple loop");
        break;
      }
    }
    for (const Edge& e : horizon) start[e.u] = -1;
    if (loop.size() != horizon.size()) throw std::logic_error("hull: horizon is not a simple loop");

    const int first = static_cast<int>(faces.size());
    const int k = static_cast<int>(loop.size());
    for (int i = 0; i < k; ++i) add(horizon[loop[i]].u, horizon[loop[i]].w, eye);
    for (int i = 0; i < k; ++i) {
      const Edge& e = horizon[loop[i]];
      Tri& t = faces[first + i];
      t.nb[0] = e.g, t.nb[1] = first + (i + 1) % k, t.nb[2] = first + (i + k - 1) % k;
      Tri& g = faces[e.g];
      for (int m = 0; m < 3; ++m)
        if (g.v[m] == e.w && g.v[(m + 1) % 3] == e.u) g.nb[m] = first + i;
    }
    for (int f : visible) {
      faces[f].alive = false;
      std::vector<int> orphans;
      orphans.swap(faces[f].outside);
      for (int p : orphans)
        if (p != eye) assign(p, first);
    }
  }
}

// Merges near-coplanar triangles into polygons. From the largest unmerged triangle, take the
// connected triangles whose vertices all lie within tol of its plane: on a convex surface that
// is a cap, one convex polygon, which is always the case for exactly coplanar faces. Should
// noise near the tolerance make it a pinched or reflex loop, grow again accepting a triangle
// only while the loop stays simple and convex (retrying refused ones until nothing changes);
// that may leave more faces than ideal, never an invalid one.
std::vector<std::vector<int>> merge_coplanar(const std::vector<Tri>& all, const std::vector<Vec3d>& P, double tol) {
  std::vector<int> id(all.size(), -1), live;
  for (size_t f = 0; f < all.size(); ++f)
    if (all[f].alive) id[f] = static_cast<int>(live.size()), live.push_back(static_cast<int>(f));
  struct T3 {
    int v[3], nb[3];
    Vec3d n;
    double d = 0, area = 0;
  };
  const int T = static_cast<int>(live.size());
  std::vector<T3> t(T);
  for (int i = 0; i < T; ++i) {
    const Tri& f = all[live[i]];
    for (int k = 0; k < 3; ++k) t[i].v[k] = f.v[k], t[i].nb[k] = id[f.nb[k]];
    const Vec3d a = P[f.v[0]], b = P[f.v[1]], c = P[f.v[2]];
    const Vec3d n = cross(b - a, c - a);
    const double l = norm(n);
    t[i].area = 0.5 * l;
    t[i].n = l > 0 ? n * (1.0 / l) : Vec3d{};
    t[i].d = dot(t[i].n, (a + b + c) * (1.0 / 3.0));
  }
  std::vector<int> order(T);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return t[x].area > t[y].area; });

  // The loop of a boundary map (vertex -> next vertex), empty unless it is one simple loop
  // with no reflex corner deeper than tol (seen along n).
  auto convex_loop = [&](const std::map<int, int>& next, const Vec3d& n) {
    std::vector<int> loop;
    for (int v = next.begin()->first; loop.size() <= next.size();) {
      loop.push_back(v);
      const auto it = next.find(v);
      if (it == next.end()) return std::vector<int>();
      if ((v = it->second) == loop[0]) break;
    }
    const size_t m = loop.size();
    if (m != next.size()) return std::vector<int>();  // a hole or a second loop
    for (size_t i = 0; i < m; ++i) {
      const Vec3d a = P[loop[(i + m - 1) % m]], b = P[loop[i]], c = P[loop[(i + 1) % m]];
      const double chord = norm(c - a);
      if (!(chord > 0) || dot(cross(b - a, c - b), n) < -tol * chord) return std::vector<int>();
    }
    return loop;
  };
  // Adds u's edges to the boundary map; false if a vertex would gain a second outgoing edge.
  auto add_edges = [](std::map<int, int>& next, const T3& u) {
    bool open[3];
    for (int k = 0; k < 3; ++k) {
      const auto it = next.find(u.v[(k + 1) % 3]);
      open[k] = !(it != next.end() && it->second == u.v[k]);
      if (!open[k]) next.erase(it);
    }
    for (int k = 0; k < 3; ++k)
      if (open[k] && !next.emplace(u.v[k], u.v[(k + 1) % 3]).second) return false;
    return true;
  };

  std::vector<int> cluster(T, -1);
  std::vector<std::vector<int>> loops;
  for (int s : order) {
    if (cluster[s] >= 0) continue;
    const int c = static_cast<int>(loops.size());
    auto flat = [&](int u) {
      for (int j = 0; j < 3; ++j)
        if (!(std::fabs(dot(t[s].n, P[t[u].v[j]]) - t[s].d) <= tol)) return false;
      return true;
    };
    std::vector<int> mem{s}, loop;
    cluster[s] = c;
    if (t[s].area > 0) {
      for (size_t q = 0; q < mem.size(); ++q)
        for (int k = 0; k < 3; ++k) {
          const int u = t[mem[q]].nb[k];
          if (cluster[u] < 0 && flat(u)) cluster[u] = c, mem.push_back(u);
        }
      std::map<int, int> next;
      for (int m : mem)
        for (int k = 0; k < 3; ++k)
          if (cluster[t[m].nb[k]] != c) next.emplace(t[m].v[k], t[m].v[(k + 1) % 3]);
      loop = convex_loop(next, t[s].n);
      if (loop.empty()) {  // guarded growth
        for (size_t q = 1; q < mem.size(); ++q) cluster[mem[q]] = -1;
        mem.resize(1);
        next.clear();
        add_edges(next, t[s]);
        for (bool grew = true; grew;) {
          grew = false;
          for (size_t q = 0; q < mem.size(); ++q)
            for (int k = 0; k < 3; ++k) {
              const int u = t[mem[q]].nb[k];
              if (cluster[u] >= 0 || !flat(u)) continue;
              std::map<int, int> nx = next;
              if (!add_edges(nx, t[u]) || convex_loop(nx, t[s].n).empty()) continue;
              next.swap(nx);
              cluster[u] = c, mem.push_back(u), grew = true;
            }
        }
        loop = convex_loop(next, t[s].n);
      }
    }
    if (loop.empty()) loop = {t[s].v[0], t[s].v[1], t[s].v[2]};
    loops.push_back(std::move(loop));
  }
  return loops;
}

// Outward planes from the stored float vertices: Newell normal of each loop, and d the largest
// n.v over all vertices, rounded up, so every vertex is inside every plane in float.
bool compute_planes(ConvexHull& h) {
  const int nf = static_cast<int>(h.face_start.size()) - 1;
  const int nv = h.num_vertices();
  auto vtx = [&](int i) { return Vec3d::load(h.vertices.data() + 3 * i); };
  h.planes.assign(4 * static_cast<size_t>(std::max(nf, 0)), 0.0f);
  for (int f = 0; f < nf; ++f) {
    const int s = h.face_start[f], e = h.face_start[f + 1];
    Vec3d c{};
    for (int i = s; i < e; ++i) c = c + vtx(h.face_vertices[i]);
    c = c * (1.0 / (e - s));
    Vec3d n{};
    for (int i = s; i < e; ++i) {
      const int j = i + 1 < e ? i + 1 : s;
      n = n + cross(vtx(h.face_vertices[i]) - c, vtx(h.face_vertices[j]) - c);
    }
    const double l = norm(n);
    if (!(l > 0) || !std::isfinite(l)) return false;
    const float nx = static_cast<float>(n.x / l), ny = static_cast<float>(n.y / l), nz = static_cast<float>(n.z / l);
    const Vec3d nn{nx, ny, nz};
    double d = -std::numeric_limits<double>::infinity();
    for (int v = 0; v < nv; ++v) d = std::max(d, dot(nn, vtx(v)));
    float df = static_cast<float>(d);
    if (static_cast<double>(df) < d) df = std::nextafter(df, std::numeric_limits<float>::infinity());
    h.planes[4 * f] = nx, h.planes[4 * f + 1] = ny, h.planes[4 * f + 2] = nz, h.planes[4 * f + 3] = df;
  }
  return true;
}

// Closed, consistently oriented, outward: every directed edge once with its reverse once,
// V - E + F = 2, every vertex on a face, and the vertex centroid inside every plane.
bool valid(const ConvexHull& h) {
  const int nv = h.num_vertices(), nf = h.num_faces();
  if (nv < 4 || nf < 4) return false;
  std::vector<std::pair<int, int>> directed;
  std::vector<int> used(nv, 0);
  for (int f = 0; f < nf; ++f) {
    const int s = h.face_start[f], e = h.face_start[f + 1];
    if (e - s < 3) return false;
    for (int i = s; i < e; ++i) {
      const int a = h.face_vertices[i], b = h.face_vertices[i + 1 < e ? i + 1 : s];
      if (a == b) return false;
      directed.emplace_back(a, b);
      used[a] = 1;
    }
  }
  std::sort(directed.begin(), directed.end());
  if (std::adjacent_find(directed.begin(), directed.end()) != directed.end()) return false;
  for (const auto& [a, b] : directed)
    if (!std::binary_search(directed.begin(), directed.end(), std::make_pair(b, a))) return false;
  if (std::count(used.begin(), used.end(), 0) != 0) return false;
  if (nv - static_cast<int>(directed.size() / 2) + nf != 2) return false;
  Vec3d c{};
  for (int v = 0; v < nv; ++v) c = c + Vec3d::load(h.vertices.data() + 3 * v);
  c = c * (1.0 / nv);
  for (int f = 0; f < nf; ++f) {
    const float* p = &h.planes[4 * f];
    if (!(dot(Vec3d::load(p), c) < p[3])) return false;
  }
  return true;
}

// Points within tol of an earlier kept point are dropped: near-duplicates would otherwise
// survive as vertices joined by sliver faces. Sweep along the axis of largest spread.
std::vector<int> weld(const std::vector<Vec3d>& P, double tol, int axis) {
  const int n = static_cast<int>(P.size());
  auto key = [&](int i) { return P[i][axis]; };
  std::vector<int> sorted(n), kept;
  std::iota(sorted.begin(), sorted.end(), 0);
  std::stable_sort(sorted.begin(), sorted.end(), [&](int i, int j) { return key(i) < key(j); });
  std::vector<char> keep(n, 0);
  for (int i = 0; i < n; ++i) {
    auto pos = std::lower_bound(sorted.begin(), sorted.end(), key(i) - tol,
                                [&](int j, double x) { return key(j) < x; });
    bool near = false;
    for (; !near && pos != sorted.end() && key(*pos) <= key(i) + tol; ++pos)
      near = *pos < i && keep[*pos] && norm(P[*pos] - P[i]) <= tol;
    if (!near) keep[i] = 1, kept.push_back(i);
  }
  return kept;
}

// The welded cloud: coordinates, grid coordinates for the exact tests, and the tolerance.
struct Cloud {
  std::vector<Vec3d> P;
  std::vector<Q3> Q;
  double tol = 0;
};

bool collinear(const Q3& a, const Q3& b, const Q3& c) {
  const int64_t bx = b.x - a.x, by = b.y - a.y, bz = b.z - a.z, cx = c.x - a.x, cy = c.y - a.y, cz = c.z - a.z;
  return i128(by) * cz == i128(bz) * cy && i128(bz) * cx == i128(bx) * cz && i128(bx) * cy == i128(by) * cx;
}

// Four of pts spanning a volume (exactly), farthest-first; false if all are coplanar.
bool find_simplex(const Cloud& cl, const std::vector<int>& pts, int s[4]) {
  if (pts.size() < 4) return false;
  const std::vector<Vec3d>& P = cl.P;
  const int a = pts[0];
  int b = -1, c = -1, d = -1;
  double best = 0;
  for (int p : pts)
    if (norm(P[p] - P[a]) > best) best = norm(P[p] - P[a]), b = p;
  if (b < 0) return false;
  const Vec3d dir = (P[b] - P[a]) * (1.0 / best);
  best = -1;
  for (int p : pts)
    if (!collinear(cl.Q[a], cl.Q[b], cl.Q[p]) && norm(cross(P[p] - P[a], dir)) > best)
      best = norm(cross(P[p] - P[a], dir)), c = p;
  if (c < 0) return false;
  Vec3d n = cross(P[b] - P[a], P[c] - P[a]);
  n = n * (1.0 / norm(n));
  best = -1;
  for (int p : pts)
    if (orient(cl.Q[a], cl.Q[b], cl.Q[c], cl.Q[p]) != 0 && std::fabs(dot(P[p] - P[a], n)) > best)
      best = std::fabs(dot(P[p] - P[a], n)), d = p;
  if (d < 0) return false;
  s[0] = a, s[1] = b, s[2] = c, s[3] = d;
  return true;
}

// Hull of pts as merged polygon loops, without the vertices on only two faces: those lie on
// a straight edge, not at a corner (kept where a face needs them to stay a polygon).
std::vector<std::vector<int>> hull_loops(const Cloud& cl, const std::vector<int>& pts, const int s[4]) {
  Quickhull qh(cl.P, cl.Q);
  qh.run(pts, s[0], s[1], s[2], s[3]);
  std::vector<std::vector<int>> loops = merge_coplanar(qh.faces, cl.P, cl.tol);
  const size_t n = cl.P.size();
  std::vector<int> faces_at(n, 0);
  for (const auto& l : loops)
    for (int v : l) ++faces_at[v];
  std::vector<char> drop(n, 0);
  for (size_t v = 0; v < n; ++v) drop[v] = faces_at[v] > 0 && faces_at[v] < 3;
  for (const auto& l : loops) {
    int kept = 0;
    for (int v : l) kept += !drop[v];
    if (kept < 3)
      for (int v : l) drop[v] = 0;
  }
  for (auto& l : loops) l.erase(std::remove_if(l.begin(), l.end(), [&](int v) { return drop[v] != 0; }), l.end());
  return loops;
}

std::vector<int> loop_vertices(const std::vector<std::vector<int>>& loops) {
  std::vector<int> v;
  for (const auto& l : loops) v.insert(v.end(), l.begin(), l.end());
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// Outward unit normal (Newell) of a loop and d, the largest n.v over its vertices.
bool loop_plane(const Cloud& cl, const std::vector<int>& l, Vec3d& n, double& d) {
  n = Vec3d{};
  for (size_t i = 0; i < l.size(); ++i) n = n + cross(cl.P[l[i]] - cl.P[l[0]], cl.P[l[(i + 1) % l.size()]] - cl.P[l[0]]);
  const double len = norm(n);
  if (!(len > 0)) return false;
  n = n * (1.0 / len);
  d = -std::numeric_limits<double>::infinity();
  for (int v : l) d = std::max(d, dot(n, cl.P[v]));
  return true;
}

// Every point of pts within tol of every face plane of loops.
bool within(const Cloud& cl, const std::vector<std::vector<int>>& loops, const std::vector<int>& pts) {
  Vec3d n;
  double d;
  for (const auto& l : loops) {
    if (!loop_plane(cl, l, n, d)) return false;
    for (int p : pts)
      if (dot(n, cl.P[p]) - d > cl.tol) return false;
  }
  return true;
}

// A solid: at least 4 faces, every vertex on 3, and thicker than tol under every face (a
// thinner hull is flat within the tolerance, and merging would fold it into two faces).
bool solid(const Cloud& cl, const std::vector<std::vector<int>>& loops) {
  const std::vector<int> used = loop_vertices(loops);
  if (loops.size() < 4 || used.size() < 4) return false;
  std::vector<int> faces_at(cl.P.size(), 0);
  for (const auto& l : loops)
    for (int v : l) ++faces_at[v];
  for (int v : used)
    if (faces_at[v] < 3) return false;
  Vec3d n;
  double d;
  for (const auto& l : loops) {
    if (!loop_plane(cl, l, n, d)) return false;
    double depth = 0;
    for (int v : used) depth = std::max(depth, d - dot(n, cl.P[v]));
    if (!(depth > cl.tol)) return false;
  }
  return true;
}

// Removes vertices within tol of the hull of the others: the tents and slivers that noise
// right at the tolerance leaves, which merging cannot see because no triangle lies in the
// plane they are close to. A vertex is tried if it is within tol of the hull of its
// neighbourhood (vertices of the faces around the faces around it), which implies it for the
// whole; it goes if the hull rebuilt without it keeps it, and every vertex removed before,
// within tol of every plane. One pass in vertex order, so the result is deterministic.
void remove_shallow_vertices(const Cloud& cl, std::vector<std::vector<int>>& loops) {
  std::vector<int> removed, mark(cl.P.size(), -1), near;
  Quickhull qh(cl.P, cl.Q);
  for (int last = -1;;) {
    const std::vector<int> used = loop_vertices(loops);
    std::vector<std::vector<int>> faces_of(cl.P.size());
    std::vector<Vec3d> normal(loops.size());
    for (size_t f = 0; f < loops.size(); ++f) {
      const std::vector<int>& l = loops[f];
      for (int v : l) faces_of[v].push_back(static_cast<int>(f));
      for (size_t i = 0; i < l.size(); ++i)
        normal[f] = normal[f] + cross(cl.P[l[i]] - cl.P[l[0]], cl.P[l[(i + 1) % l.size()]] - cl.P[l[0]]);
      if (norm(normal[f]) > 0) normal[f] = normal[f] * (1.0 / norm(normal[f]));
    }
    int cand = -1;
    for (int v : used) {
      if (v <= last) continue;
      near.clear();
      mark[v] = v;
      for (int f : faces_of[v])
        for (int u : loops[f])
          for (int g : faces_of[u])
            for (int w : loops[g])
              if (mark[w] != v) mark[w] = v, near.push_back(w);
      // Quick rejection: a plane along the mean normal at v already separates it by > tol.
      Vec3d m{};
      for (int f : faces_of[v]) m = m + normal[f];
      double top = -std::numeric_limits<double>::infinity();
      for (int w : near) top = std::max(top, dot(m, cl.P[w]));
      if (norm(m) > 0 && dot(m, cl.P[v]) - top > cl.tol * norm(m)) continue;
      std::sort(near.begin(), near.end());
      int s[4];
      if (!find_simplex(cl, near, s)) continue;
      qh.run(near, s[0], s[1], s[2], s[3]);
      double out = -std::numeric_limits<double>::infinity();
      for (const Tri& t : qh.faces)
        if (t.alive) out = std::max(out, dot(t.n, cl.P[v]) - t.d);
      if (out <= cl.tol) {
        cand = v;
        break;
      }
    }
    if (cand < 0) return;
    last = cand;
    std::vector<int> rest;
    for (int v : used)
      if (v != cand) rest.push_back(v);
    int s[4];
    if (!find_simplex(cl, rest, s)) continue;
    std::vector<std::vector<int>> trial = hull_loops(cl, rest, s);
    removed.push_back(cand);
    if (solid(cl, trial) && within(cl, trial, removed))
      loops.swap(trial);
    else
      removed.pop_back();
  }
}

}  // namespace

spu::HullView ConvexHull::view() const {
  spu::HullView v;
  v.num_vertices = num_vertices();
  v.vertices = vertices.data();
  v.num_faces = num_faces();
  v.planes = planes.data();
  v.face_start = face_start.data();
  v.face_vertices = face_vertices.data();
  v.num_edges = num_edges();
  v.edges = edges.data();
  return v;
}

ConvexHull compute_convex_hull(const float* points, int count, const HullLimits& limits) {
  if (count < 4) fail("needs at least 4 points, got " + std::to_string(count));
  if (count > limits.max_points)
    fail(std::to_string(count) + " points is more than the limit of " + std::to_string(limits.max_points));
  if (!points) fail("no point array given");
  std::vector<Vec3d> P(count);
  for (int i = 0; i < count; ++i) {
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(points[3 * i + k]))
        fail("point " + std::to_string(i) + " is not finite (" + "xyz"[k] + " = " + num(points[3 * i + k]) + ")");
    P[i] = Vec3d::load(points + 3 * i);
  }

  // One tolerance: relative to the cloud's size plus float rounding at its distance from
  // the origin. Points closer than this to a face count as on it.
  Vec3d lo = P[0], hi = P[0];
  double M = 0;
  for (const Vec3d& p : P) {
    lo = min(lo, p);
    hi = max(hi, p);
    M = std::max({M, std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
  }
  const Vec3d span = hi - lo;
  const double L = norm(span);
  const double tol = 1e-6 * L + 8.0 * FLT_EPSILON * M;
  const std::string cloud = "degenerate point cloud: all " + std::to_string(count) + " points ";
  if (L <= tol) fail(cloud + "coincide (within " + num(tol) + ")");

  // From here on P holds the welded points; src maps them back to the input.
  const std::vector<int> src = weld(P, tol, span.x >= span.y && span.x >= span.z ? 0 : span.y >= span.z ? 1 : 2);
  for (size_t i = 0; i < src.size(); ++i) P[i] = P[src[i]];
  P.resize(src.size());
  const int n = static_cast<int>(P.size());

  // Initial simplex from the extreme points; its failures are the degenerate clouds.
  int ext[6] = {0, 0, 0, 0, 0, 0};
  for (int i = 1; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      if (P[i][k] < P[ext[k]][k]) ext[k] = i;
      if (P[i][k] > P[ext[3 + k]][k]) ext[3 + k] = i;
    }
  int a = ext[0], b = ext[3];
  double best = -1;
  for (int i = 0; i < 6; ++i)
    for (int j = i + 1; j < 6; ++j) {
      const double d = norm(P[ext[i]] - P[ext[j]]);
      if (d > best) best = d, a = ext[i], b = ext[j];
    }
  const Vec3d dir = (P[b] - P[a]) * (1.0 / best);
  int c = -1;
  best = -1;
  for (int i = 0; i < n; ++i) {
    const double d = norm(cross(P[i] - P[a], dir));
    if (d > best) best = d, c = i;
  }
  if (best <= tol) fail(cloud + "are collinear (within " + num(tol) + ")");
  Vec3d nrm = cross(P[b] - P[a], P[c] - P[a]);
  nrm = nrm * (1.0 / norm(nrm));
  int d4 = -1;
  best = -1;
  for (int i = 0; i < n; ++i) {
    const double d = std::fabs(dot(P[i] - P[a], nrm));
    if (d > best) best = d, d4 = i;
  }
  if (best <= tol) fail(cloud + "are coplanar (within " + num(tol) + ")");

  // Exact topology on the snapped points.
  Cloud cl;
  const double E = std::max({span.x, span.y, span.z});
  const double g = kGrid / E;
  for (const Vec3d& p : P) cl.Q.push_back({std::llround((p.x - lo.x) * g), std::llround((p.y - lo.y) * g), std::llround((p.z - lo.z) * g)});
  cl.P = std::move(P);
  cl.tol = tol;
  if (orient(cl.Q[a], cl.Q[b], cl.Q[c], cl.Q[d4]) == 0) fail(cloud + "are coplanar");
  std::vector<int> all(n);
  std::iota(all.begin(), all.end(), 0);
  const int simplex[4] = {a, b, c, d4};
  std::vector<std::vector<int>> loops = hull_loops(cl, all, simplex);
  if (!solid(cl, loops)) fail(cloud + "are coplanar (the hull is no thicker than " + num(tol) + ")");
  remove_shallow_vertices(cl, loops);
  std::vector<int> index(n, -1);
  for (int v : loop_vertices(loops)) index[v] = 0;

  ConvexHull h;
  h.tolerance = tol;
  for (int i = 0; i < n; ++i)  // vertices in input order
    if (index[i] == 0) {
      index[i] = static_cast<int>(h.source.size());
      h.source.push_back(src[i]);
      h.vertices.insert(h.vertices.end(), points + 3 * src[i], points + 3 * src[i] + 3);
    }
  if (h.num_vertices() > limits.max_vertices)
    fail("the hull of these " + std::to_string(count) + " points has " + std::to_string(h.num_vertices()) +
         " vertices, more than the limit of " + std::to_string(limits.max_vertices) + "; simplify the point cloud");
  h.face_start.push_back(0);
  for (auto& l : loops) {
    for (int& v : l) v = index[v];
    std::rotate(l.begin(), std::min_element(l.begin(), l.end()), l.end());
    h.face_vertices.insert(h.face_vertices.end(), l.begin(), l.end());
    h.face_start.push_back(static_cast<int32_t>(h.face_vertices.size()));
  }
  for (const auto& l : loops)
    for (size_t i = 0; i < l.size(); ++i) {
      const int u = l[i], w = l[(i + 1) % l.size()];
      if (u < w) h.edges.push_back(u), h.edges.push_back(w);
    }
  if (!compute_planes(h) || !valid(h)) fail_invalid();
  return h;
}

void translate_hull(ConvexHull& hull, const double offset[3]) {
  for (size_t i = 0; i < hull.vertices.size(); ++i)
    hull.vertices[i] = static_cast<float>(static_cast<double>(hull.vertices[i]) + offset[i % 3]);
  if (!compute_planes(hull) || !valid(hull)) fail_invalid();
}

}  // namespace cellphys::ppe
