// cellphys_bench: runs one scene file in one engine configuration and prints what happened as
// one JSON object on stdout. scripts/bench drives it (sweeps, references, charts).
//
//   cellphys_bench info
//   cellphys_bench run SCENE --engine E [--variant V] [--dt H] [--tolerance T] [--workers N]
//                  [--iterations N] --duration S [--reps R] [--record K]
//       Steps S simulated seconds R times (each from a freshly built world) and reports the
//       wall time of each run's stepping (median and all), and the first run's trajectory of
//       every dynamic body every K steps (K = 0: the initial and final states only).
//   cellphys_bench throughput SCENE --engine E [...] [--warmup W] --timed N --settle S
//                  [--until-asleep 1]
//       Steps W simulated seconds untimed (0: none), times N single steps (bodies awake), steps
//       on untimed to S simulated seconds, then times N more (most bodies asleep): the median
//       of each phase. --until-asleep 1 makes S a limit: the settling stops at the first step
//       after which no body is active (settled_at says when, in simulated seconds; null if it
//       never did, settle_wall_s how long it took).
//   cellphys_bench rest SCENE --engine E [...] --steps N [--budget W]
//       For a structure built at rest (a pyramid): times N single steps from the start and
//       reports the median and mean ms per step (the mean leaves out the first step, as Box3D's
//       benchmark does, and the first is reported alone), then how far the world moved from its
//       start: the top's sink (the bodies that start highest: the most any of them went down),
//       the largest sideways drift of any body (its displacement across gravity), the largest
//       drop of any body, and the kinetic energy at the end (translation and rotation, J), the
//       fastest body at the end. --budget W stops after W wall seconds of stepping (steps_done
//       says where; the figures are then those of that step).
//   cellphys_bench stability SCENE --engine E [...] --dts H1,H2,... --steps N [--max-speed V]
//                  [--separate-within S] [--separation D]
//       Runs N steps at each step size, largest first, until one stays bounded; reports how each
//       larger one failed: blow-up (non-finite or runaway state), tunnelling (a body through a
//       ground plane or through the body below it), stretch (a joint opened by more than 10%
//       of its bodies' distance), energy gain (over 10% above the start). For spawns in overlap,
//       which gain energy by design: --max-speed V fails a body faster than V m/s (too fast)
//       instead of checking the energy; --separate-within S runs each step size for at least S
//       simulated seconds and fails it if two boxes, or a box and a plane, still overlap by more
//       than D m (default 0.01) at S (overlap left).
//   cellphys_bench situation SCENE --engine E [--variant V] [--dt H] --duration S [--separation D]
//                  [--budget W]
//       Steps S simulated seconds, timing the steps, and measures after each one (untimed): how
//       deep each box is in what it rested on at the start (the box below or the ground; largest
//       and final), the deepest overlap of any pair, the time from which no pair overlaps by more
//       than D m (default 0.01) to the end, the fastest body (over the run and at the end), the
//       highest centre, the closest two centres at the end, the steps the engine reports failed,
//       the energy (kinetic + gravitational + spring) at every whole simulated second, and each
//       body's first and last position. --budget W stops after W wall seconds of stepping
//       (steps_done says where).
// Exit status: 0 with a JSON object (its "status" is ok, unsupported or error), 2 on bad usage.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <btBulletDynamicsCommon.h>
#include <mujoco/mujoco.h>
#include <ode/ode.h>

#include "bench/peers/peer.h"
#include "bench/tool/overlap.h"
#include "runtime/base/simd.h"

namespace {

using namespace cellphys;
using namespace cellphys::bench;
using Clock = std::chrono::steady_clock;

std::string jstr(const std::string& s) {
  std::string o = "\"";
  for (char ch : s) {
    if (ch == '"' || ch == '\\') o += '\\', o += ch;
    else if (ch == '\n') o += "\\n";
    else if (static_cast<unsigned char>(ch) < 0x20) o += ' ';
    else o += ch;
  }
  return o + "\"";
}

std::string jnum(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

bool finite_state(const State& s) {
  for (double x : {s.p[0], s.p[1], s.p[2], s.v[0], s.v[1], s.v[2], s.w[0], s.w[1], s.w[2], s.q[0]})
    if (!std::isfinite(x)) return false;
  return true;
}

double speed(const State& s) { return std::sqrt(s.v[0] * s.v[0] + s.v[1] * s.v[1] + s.v[2] * s.v[2]); }

struct Args {
  std::string command, scene, engine = "cellphys", variant;
  double dt = 0, tolerance = 0, duration = 1, settle = 0, warmup = 0;
  double max_speed = 0, separate_within = 0, separation = 0.01, budget = 0;
  bool until_asleep = false;
  int workers = 0, iterations = 0, reps = 1, record = 0, timed = 20, steps = 400;
  std::vector<double> dts;
};

[[noreturn]] void usage(const std::string& why) {
  std::cerr << "cellphys_bench: " << why << "\n(see the header of bench/tool/cellphys_bench.cpp)\n";
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  if (argc < 2) usage("no command");
  a.command = argv[1];
  int i = 2;
  if (a.command != "info") {
    if (argc < 3) usage("no scene file");
    a.scene = argv[2];
    i = 3;
  }
  for (; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) usage("missing value for " + k);
    const std::string v = argv[++i];
    if (k == "--engine") a.engine = v;
    else if (k == "--variant") a.variant = v;
    else if (k == "--dt") a.dt = std::stod(v);
    else if (k == "--tolerance") a.tolerance = std::stod(v);
    else if (k == "--duration") a.duration = std::stod(v);
    else if (k == "--settle") a.settle = std::stod(v);
    else if (k == "--warmup") a.warmup = std::stod(v);
    else if (k == "--workers") a.workers = std::stoi(v);
    else if (k == "--iterations") a.iterations = std::stoi(v);
    else if (k == "--reps") a.reps = std::max(1, std::stoi(v));
    else if (k == "--record") a.record = std::stoi(v);
    else if (k == "--max-speed") a.max_speed = std::stod(v);
    else if (k == "--separate-within") a.separate_within = std::stod(v);
    else if (k == "--separation") a.separation = std::stod(v);
    else if (k == "--budget") a.budget = std::stod(v);
    else if (k == "--until-asleep") a.until_asleep = std::stoi(v) != 0;
    else if (k == "--timed") a.timed = std::max(1, std::stoi(v));
    else if (k == "--steps") a.steps = std::max(1, std::stoi(v));
    else if (k == "--dts") {
      std::stringstream ss(v);
      std::string t;
      while (std::getline(ss, t, ',')) a.dts.push_back(std::stod(t));
    } else usage("unknown option " + k);
  }
  return a;
}

EngineConfig config_of(const Args& a, double dt) {
  EngineConfig c;
  c.engine = a.engine;
  c.variant = a.variant;
  c.dt = dt;
  c.tolerance = a.tolerance;
  c.workers = a.workers;
  c.iterations = a.iterations;
  return c;
}

std::vector<size_t> dynamic_bodies(const scene::SceneDesc& s) {
  std::vector<size_t> out;
  for (size_t i = 0; i < s.bodies.size(); ++i) {
    bool plane = false;
    for (const auto& sh : s.shapes)
      if (sh.name == s.bodies[i].shape) plane = sh.type == spu::ShapeType::plane;
    if (!s.bodies[i].is_static && !plane) out.push_back(i);
  }
  return out;
}

void print_state(std::ostream& o, double t, size_t i, const State& s) {
  o << "[" << jnum(t) << "," << i;
  for (double x : s.p) o << "," << jnum(x);
  for (double x : s.q) o << "," << jnum(x);
  for (double x : s.v) o << "," << jnum(x);
  for (double x : s.w) o << "," << jnum(x);
  o << "]";
}

int cmd_info() {
  std::cout << "{\"status\":\"ok\",\"compiler\":" << jstr(std::string("g++ ") + __VERSION__)
            << ",\"simd_path\":" << jstr(simd::kPathName) << ",\"bullet\":" << btGetVersion()
            << ",\"ode\":" << jstr(dGetConfiguration()) << ",\"mujoco\":" << mj_version() << "}\n";
  return 0;
}

int cmd_run(const Args& a, const scene::SceneDesc& sc) {
  const double dt = a.dt > 0 ? a.dt : sc.settings.dt;
  const long steps = std::max(1L, std::lround(a.duration / dt));
  const std::vector<size_t> dyn = dynamic_bodies(sc);
  std::vector<double> walls;
  std::ostringstream traj;
  traj.precision(9);
  bool finite = true;
  long done = 0;
  std::string label;
  for (int r = 0; r < a.reps; ++r) {
    auto peer = make_peer(sc, config_of(a, dt));
    label = peer->label();
    const bool rec = r == 0;
    bool first = true;
    auto record = [&](long n) {
      for (size_t i : dyn) {
        traj << (first ? "" : ",");
        first = false;
        print_state(traj, n * dt, i, peer->state(i));
      }
    };
    if (rec) record(0);
    double wall = 0;
    long n = 0;
    // Time in chunks between recordings so that recording costs nothing.
    const long chunk = a.record > 0 ? a.record : steps;
    while (n < steps) {
      const long m = std::min(chunk, steps - n);
      const auto t0 = Clock::now();
      for (long k = 0; k < m; ++k) peer->step();
      wall += std::chrono::duration<double>(Clock::now() - t0).count();
      n += m;
      bool ok = true;
      for (size_t i : dyn) ok = ok && finite_state(peer->state(i));
      if (rec && (a.record > 0 || n == steps || !ok)) record(n);
      if (!ok) {
        finite = false;
        break;
      }
    }
    if (rec) done = n;
    walls.push_back(wall);
    if (!finite) break;
  }
  const double med = median(walls);
  std::cout << "{\"status\":\"ok\",\"label\":" << jstr(label) << ",\"dt\":" << jnum(dt) << ",\"steps\":" << steps
            << ",\"steps_done\":" << done << ",\"finite\":" << (finite ? "true" : "false")
            << ",\"wall_s_median\":" << jnum(med) << ",\"wall_s\":[";
  for (size_t k = 0; k < walls.size(); ++k) std::cout << (k ? "," : "") << jnum(walls[k]);
  std::cout << "],\"cpu_s_per_sim_s\":" << jnum(med / (steps * dt)) << ",\"ms_per_step\":" << jnum(1e3 * med / steps)
            << ",\"trajectory\":[" << traj.str() << "]}\n";
  return 0;
}

int cmd_throughput(const Args& a, const scene::SceneDesc& sc) {
  const double dt = a.dt > 0 ? a.dt : sc.settings.dt;
  const auto tb = Clock::now();
  auto peer = make_peer(sc, config_of(a, dt));
  const double build_s = std::chrono::duration<double>(Clock::now() - tb).count();
  const std::vector<size_t> dyn = dynamic_bodies(sc);
  auto phase = [&](std::vector<double>& ms) {
    for (int k = 0; k < a.timed; ++k) {
      const auto t0 = Clock::now();
      peer->step();
      ms.push_back(1e3 * std::chrono::duration<double>(Clock::now() - t0).count());
    }
  };
  std::vector<double> awake, settled;
  long n = 0;
  for (const long w = std::lround(a.warmup / dt); n < w; ++n) peer->step();
  phase(awake);
  const long active_awake = peer->active_bodies();
  n += a.timed;
  const long settle_steps = std::lround(a.settle / dt);
  double settled_at = NAN;
  if (a.until_asleep && peer->active_bodies() == 0) settled_at = n * dt;
  const auto ts = Clock::now();
  while (n < settle_steps && !std::isfinite(settled_at)) {
    peer->step(), ++n;
    if (a.until_asleep && peer->active_bodies() == 0) settled_at = n * dt;
  }
  const double settle_wall = std::chrono::duration<double>(Clock::now() - ts).count();
  const long active_before = a.settle > 0 ? peer->active_bodies() : -1;
  if (a.settle > 0) phase(settled);
  bool finite = true;
  for (size_t i : dyn) finite = finite && finite_state(peer->state(i));
  std::cout << "{\"status\":\"ok\",\"label\":" << jstr(peer->label()) << ",\"dt\":" << jnum(dt)
            << ",\"bodies\":" << dyn.size() << ",\"build_s\":" << jnum(build_s)
            << ",\"ms_awake\":" << jnum(median(awake)) << ",\"active_awake\":" << active_awake
            << ",\"ms_settled\":" << jnum(median(settled)) << ",\"active_settled\":"
            << (a.settle > 0 ? peer->active_bodies() : -1) << ",\"active_before_settled\":" << active_before
            << ",\"settled_at\":" << jnum(settled_at) << ",\"settle_wall_s\":" << jnum(settle_wall)
            << ",\"finite\":" << (finite ? "true" : "false") << "}\n";
  return 0;
}

int cmd_rest(const Args& a, const scene::SceneDesc& sc) {
  const double dt = a.dt > 0 ? a.dt : sc.settings.dt;
  const auto tb = Clock::now();
  auto peer = make_peer(sc, config_of(a, dt));
  const double build_s = std::chrono::duration<double>(Clock::now() - tb).count();
  const std::vector<size_t> dyn = dynamic_bodies(sc);
  const std::vector<BodyInfo> info = body_info(sc);
  std::vector<State> start(sc.bodies.size());
  for (size_t i : dyn) start[i] = peer->state(i);
  // "Down" is along gravity (or -z without it); sideways is across it.
  double down[3] = {0, 0, -1};
  const auto& g = sc.settings.globals.gravity;
  const double gn = std::sqrt(double(g[0]) * g[0] + double(g[1]) * g[1] + double(g[2]) * g[2]);
  if (gn > 0)
    for (int k = 0; k < 3; ++k) down[k] = g[k] / gn;
  auto depth = [&](const State& s) { return s.p[0] * down[0] + s.p[1] * down[1] + s.p[2] * down[2]; };
  double top = INFINITY;  // the smallest depth: the highest start
  for (size_t i : dyn) top = std::min(top, depth(start[i]));
  std::vector<double> ms;
  double wall = 0;
  bool finite = true;
  long n = 0;
  while (n < a.steps && !(a.budget > 0 && wall > a.budget)) {
    const auto t0 = Clock::now();
    peer->step();
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    wall += s;
    ms.push_back(1e3 * s);
    ++n;
  }
  double top_sink = -INFINITY, drift = 0, drop = -INFINITY, kinetic = 0, fastest = 0;
  long tops = 0;
  for (size_t i : dyn) {
    const State s = peer->state(i);
    if (!finite_state(s)) {
      finite = false;
      continue;
    }
    const double sink = depth(s) - depth(start[i]);
    if (depth(start[i]) < top + 1e-3) top_sink = std::max(top_sink, sink), ++tops;
    drop = std::max(drop, sink);
    double d[3], across = 0;
    for (int k = 0; k < 3; ++k) d[k] = s.p[k] - start[i].p[k];
    const double along = d[0] * down[0] + d[1] * down[1] + d[2] * down[2];
    for (int k = 0; k < 3; ++k) across += (d[k] - along * down[k]) * (d[k] - along * down[k]);
    drift = std::max(drift, std::sqrt(across));
    double Iw[3];
    world_inertia_mul(s.q, info[i].inertia, s.w, Iw);
    kinetic += 0.5 * info[i].mass * (s.v[0] * s.v[0] + s.v[1] * s.v[1] + s.v[2] * s.v[2]) +
               0.5 * (s.w[0] * Iw[0] + s.w[1] * Iw[1] + s.w[2] * Iw[2]);
    fastest = std::max(fastest, speed(s));
  }
  double mean = NAN;
  if (ms.size() > 1) {
    mean = 0;
    for (size_t k = 1; k < ms.size(); ++k) mean += ms[k];
    mean /= double(ms.size() - 1);
  }
  std::cout << "{\"status\":\"ok\",\"label\":" << jstr(peer->label()) << ",\"dt\":" << jnum(dt)
            << ",\"bodies\":" << dyn.size() << ",\"build_s\":" << jnum(build_s) << ",\"steps\":" << a.steps
            << ",\"steps_done\":" << n << ",\"wall_s\":" << jnum(wall) << ",\"ms_per_step\":" << jnum(median(ms))
            << ",\"ms_mean\":" << jnum(mean) << ",\"ms_first\":" << jnum(ms.empty() ? NAN : ms[0])
            << ",\"active_end\":" << peer->active_bodies() << ",\"tops\":" << tops
            << ",\"top_sink\":" << jnum(top_sink) << ",\"max_drift\":" << jnum(drift) << ",\"max_drop\":" << jnum(drop)
            << ",\"kinetic_end\":" << jnum(kinetic) << ",\"speed_end\":" << jnum(fastest)
            << ",\"finite\":" << (finite ? "true" : "false") << "}\n";
  return 0;
}

// ---- stability ----

struct Joint {
  int a, b;
  double pa[3], pb[3], ref, k;
};

struct Checker {
  const scene::SceneDesc& sc;
  std::vector<BodyInfo> info;
  std::vector<size_t> dyn;
  std::vector<Joint> joints;
  std::vector<std::pair<int, int>> stacked;  // (lower, upper) pairs sharing a vertical line
  std::vector<std::pair<double, double>> stacked_gap;
  double e0 = 0, escale = 0;
  double max_speed = 0;  // > 0: a faster body fails, and the energy is not checked

  explicit Checker(const scene::SceneDesc& s) : sc(s), info(body_info(s)), dyn(dynamic_bodies(s)) {
    for (const auto& f : sc.forces) {
      if (f.type != "point_to_point" && f.type != "spring") continue;
      Joint j;
      j.a = body_index(sc, f.a);
      j.b = body_index(sc, f.b);
      for (int k = 0; k < 3; ++k) {
        for (const auto& [n, v] : f.params) {
          if (n == "point_a") j.pa[k] = v[k];
          if (n == "point_b") j.pb[k] = v[k];
        }
      }
      j.k = 0;
      for (const auto& [n, v] : f.params)
        if (n == "stiffness") j.k = v[0];
      double d = 0;
      for (int k = 0; k < 3; ++k) {
        const double e =
            sc.bodies[j.a].state.position[k] - (j.b >= 0 ? double(sc.bodies[j.b].state.position[k]) : j.pb[k]);
        d += e * e;
      }
      j.ref = f.type == "point_to_point" ? std::sqrt(d) : -1;  // springs are not joints
      joints.push_back(j);
    }
    for (size_t x : dyn)
      for (size_t y : dyn) {
        const float *A = sc.bodies[x].state.position, *B = sc.bodies[y].state.position;
        if (x != y && std::hypot(A[0] - B[0], A[1] - B[1]) < 1e-3 && B[2] > A[2])
          stacked.push_back({int(x), int(y)});
      }
  }
  double energy(const std::vector<State>& s) const {
    double e = 0;
    const auto& g = sc.settings.globals.gravity;
    for (size_t i : dyn) {
      const State& x = s[i];
      double Iw[3];
      world_inertia_mul(x.q, info[i].inertia, x.w, Iw);
      e += 0.5 * info[i].mass * (x.v[0] * x.v[0] + x.v[1] * x.v[1] + x.v[2] * x.v[2]);
      e += 0.5 * (x.w[0] * Iw[0] + x.w[1] * Iw[1] + x.w[2] * Iw[2]);
      e -= info[i].mass * (g[0] * x.p[0] + g[1] * x.p[1] + g[2] * x.p[2]);
    }
    for (const auto& f : sc.forces) {
      if (f.type != "spring") continue;
      const int a = body_index(sc, f.a), b = body_index(sc, f.b);
      double pa[3] = {}, pb[3] = {}, k = 0, rest = 0;
      for (const auto& [n, v] : f.params) {
        if (n == "point_a") std::copy(v.begin(), v.begin() + 3, pa);
        if (n == "point_b") std::copy(v.begin(), v.begin() + 3, pb);
        if (n == "stiffness") k = v[0];
        if (n == "rest_length") rest = v[0];
      }
      double xa[3], xb[3];
      quat_rotate(s[a].q, pa, xa);
      for (int q = 0; q < 3; ++q) xa[q] += s[a].p[q];
      if (b >= 0) {
        quat_rotate(s[b].q, pb, xb);
        for (int q = 0; q < 3; ++q) xb[q] += s[b].p[q];
      } else {
        std::copy(pb, pb + 3, xb);
      }
      const double len = std::sqrt((xa[0] - xb[0]) * (xa[0] - xb[0]) + (xa[1] - xb[1]) * (xa[1] - xb[1]) +
                                   (xa[2] - xb[2]) * (xa[2] - xb[2]));
      e += 0.5 * k * (len - rest) * (len - rest);
    }
    return e;
  }
  // "" when fine, else the failure mode.
  std::string check(const std::vector<State>& s) const {
    for (size_t i : dyn) {
      if (!finite_state(s[i])) return "blow-up";
      for (int k = 0; k < 3; ++k)
        if (std::fabs(s[i].p[k]) > 1e4 || std::fabs(s[i].v[k]) > 1e4) return "blow-up";
    }
    for (const auto& b : sc.bodies) {
      for (const auto& sh : sc.shapes) {
        if (sh.name != b.shape || sh.type != spu::ShapeType::plane) continue;
        for (size_t i : dyn)
          if (sh.normal[0] * s[i].p[0] + sh.normal[1] * s[i].p[1] + sh.normal[2] * s[i].p[2] < sh.offset)
            return "tunnelling";
      }
    }
    for (auto [lo, up] : stacked) {
      const double d0 = sc.bodies[up].state.position[2] - sc.bodies[lo].state.position[2];
      if (s[up].p[2] - s[lo].p[2] < 0.5 * d0) return "tunnelling";
    }
    for (const Joint& j : joints) {
      if (j.ref <= 0) continue;
      double xa[3], xb[3];
      quat_rotate(s[j.a].q, j.pa, xa);
      for (int q = 0; q < 3; ++q) xa[q] += s[j.a].p[q];
      if (j.b >= 0) {
        quat_rotate(s[j.b].q, j.pb, xb);
        for (int q = 0; q < 3; ++q) xb[q] += s[j.b].p[q];
      } else {
        std::copy(j.pb, j.pb + 3, xb);
      }
      if (std::sqrt((xa[0] - xb[0]) * (xa[0] - xb[0]) + (xa[1] - xb[1]) * (xa[1] - xb[1]) +
                    (xa[2] - xb[2]) * (xa[2] - xb[2])) > 0.1 * j.ref)
        return "stretch";
    }
    if (max_speed > 0) {
      for (size_t i : dyn)
        if (speed(s[i]) > max_speed) return "too fast";
      return "";
    }
    if (energy(s) - e0 > 0.1 * escale) return "energy gain";
    return "";
  }
};

int cmd_stability(const Args& a, const scene::SceneDesc& sc) {
  std::vector<double> dts = a.dts;
  std::sort(dts.rbegin(), dts.rend());
  Checker ck(sc);
  ck.max_speed = a.max_speed;
  const Overlaps overlaps(sc);
  std::vector<State> s(sc.bodies.size());
  std::ostringstream out;
  double stable = NAN;
  std::string label;
  bool first = true;
  for (double dt : dts) {
    auto peer = make_peer(sc, config_of(a, dt));
    label = peer->label();
    for (size_t i = 0; i < s.size(); ++i) s[i] = peer->state(i);
    ck.e0 = ck.energy(s);
    ck.escale = std::max(std::fabs(ck.e0), 1e-3);
    std::string mode;
    const long separate_at = a.separate_within > 0 ? std::lround(std::ceil(a.separate_within / dt - 1e-9)) : -1;
    const long steps = std::max<long>(a.steps, separate_at);
    long k = 0;
    for (; k < steps && mode.empty(); ++k) {
      peer->step();
      for (size_t i : ck.dyn) s[i] = peer->state(i);
      mode = ck.check(s);
      if (mode.empty() && k + 1 == separate_at && overlaps.deepest(s) > a.separation) mode = "overlap left";
    }
    out << (first ? "" : ",") << "{\"dt\":" << jnum(dt) << ",\"mode\":" << jstr(mode.empty() ? "ok" : mode)
        << ",\"at_step\":" << k << "}";
    first = false;
    if (mode.empty()) {
      stable = dt;
      break;
    }
  }
  std::cout << "{\"status\":\"ok\",\"label\":" << jstr(label) << ",\"largest_stable_dt\":" << jnum(stable)
            << ",\"tried\":[" << out.str() << "]}\n";
  return 0;
}

int cmd_situation(const Args& a, const scene::SceneDesc& sc) {
  const double dt = a.dt > 0 ? a.dt : sc.settings.dt;
  const long steps = std::max(1L, std::lround(a.duration / dt));
  const long per_second = std::max(1L, std::lround(1.0 / dt));
  auto peer = make_peer(sc, config_of(a, dt));
  const Checker ck(sc);
  const Overlaps overlaps(sc);
  const std::vector<int>& below = overlaps.below();
  std::vector<State> s(sc.bodies.size());
  for (size_t i = 0; i < s.size(); ++i) s[i] = peer->state(i);
  const std::vector<State> start = s;
  std::vector<double> rest_max(s.size(), 0), rest(s.size(), 0), energy{ck.energy(s)};
  double max_speed = 0, max_height = -INFINITY, deepest_max = 0, deepest = 0, wall = 0;
  long failed = 0, last_overlap = overlaps.deepest(s) > a.separation ? 0 : -1, n = 0;
  bool says_failed = true, finite = true;
  for (size_t i : ck.dyn) max_height = std::max(max_height, s[i].p[2]);
  while (n < steps && finite && !(a.budget > 0 && wall > a.budget)) {
    const auto t0 = Clock::now();
    peer->step();
    wall += std::chrono::duration<double>(Clock::now() - t0).count();
    ++n;
    const int f = peer->last_step_failed();
    says_failed = says_failed && f >= 0;
    failed += f > 0;
    for (size_t i : ck.dyn) {
      s[i] = peer->state(i);
      finite = finite && finite_state(s[i]);
      max_speed = std::max(max_speed, speed(s[i]));
      max_height = std::max(max_height, s[i].p[2]);
    }
    if (!finite) break;
    for (size_t i : ck.dyn) {
      if (below[i] < 0) continue;
      rest[i] = std::max(0.0, overlaps.depth(i, below[i], s));
      rest_max[i] = std::max(rest_max[i], rest[i]);
    }
    deepest = overlaps.deepest(s);
    deepest_max = std::max(deepest_max, deepest);
    if (deepest > a.separation) last_overlap = n;
    if (n % per_second == 0) energy.push_back(ck.energy(s));
  }
  double min_distance = INFINITY, speed_end = 0;
  for (size_t i : ck.dyn) speed_end = std::max(speed_end, speed(s[i]));
  for (size_t x : ck.dyn)
    for (size_t y : ck.dyn)
      if (x < y)
        min_distance = std::min(min_distance, std::sqrt((s[x].p[0] - s[y].p[0]) * (s[x].p[0] - s[y].p[0]) +
                                                        (s[x].p[1] - s[y].p[1]) * (s[x].p[1] - s[y].p[1]) +
                                                        (s[x].p[2] - s[y].p[2]) * (s[x].p[2] - s[y].p[2])));
  // Separated: no pair over the bound from some step to the end of a finished run.
  const bool separated = finite && n == steps && last_overlap < n;
  std::cout << "{\"status\":\"ok\",\"label\":" << jstr(peer->label()) << ",\"dt\":" << jnum(dt) << ",\"steps\":" << steps
            << ",\"steps_done\":" << n << ",\"finite\":" << (finite ? "true" : "false")
            << ",\"ms_per_step\":" << jnum(1e3 * wall / std::max(1L, n)) << ",\"failed_steps\":"
            << (says_failed ? std::to_string(failed) : "null") << ",\"max_speed\":" << jnum(max_speed)
            << ",\"speed_end\":" << jnum(speed_end)
            << ",\"max_height\":" << jnum(max_height) << ",\"deepest_max\":" << jnum(deepest_max)
            << ",\"deepest_end\":" << jnum(deepest) << ",\"separated_at\":"
            << (separated ? jnum((last_overlap + 1) * dt) : "null") << ",\"min_distance_end\":" << jnum(min_distance)
            << ",\"energy\":[";
  for (size_t k = 0; k < energy.size(); ++k) std::cout << (k ? "," : "") << jnum(energy[k]);
  std::cout << "],\"bodies\":[";
  bool first = true;
  for (size_t i : ck.dyn) {
    std::cout << (first ? "" : ",") << "{\"index\":" << i << ",\"id\":" << jstr(sc.bodies[i].id)
              << ",\"below\":" << below[i] << ",\"rest_max\":" << jnum(rest_max[i]) << ",\"rest_end\":" << jnum(rest[i])
              << ",\"start\":[" << jnum(start[i].p[0]) << "," << jnum(start[i].p[1]) << "," << jnum(start[i].p[2])
              << "],\"end\":[" << jnum(s[i].p[0]) << "," << jnum(s[i].p[1]) << "," << jnum(s[i].p[2]) << "]}";
    first = false;
  }
  std::cout << "]}\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  try {
    if (a.command == "info") return cmd_info();
    const scene::SceneDesc sc = scene::load_scene(a.scene);
    if (a.command == "run") return cmd_run(a, sc);
    if (a.command == "throughput") return cmd_throughput(a, sc);
    if (a.command == "rest") return cmd_rest(a, sc);
    if (a.command == "stability") return cmd_stability(a, sc);
    if (a.command == "situation") return cmd_situation(a, sc);
    usage("unknown command " + a.command);
  } catch (const Unsupported& e) {
    std::cout << "{\"status\":\"unsupported\",\"reason\":" << jstr(e.what()) << "}\n";
  } catch (const std::exception& e) {
    std::cout << "{\"status\":\"error\",\"reason\":" << jstr(e.what()) << "}\n";
  }
  return 0;
}
