// MuJoCo 2.2.2: the scene written as MJCF (a free joint per dynamic body, its mass and full
// inertia tensor given explicitly, static shapes as world geoms) and loaded from memory
// through a VFS. Variants are MuJoCo's integrators: "euler" (semi-implicit Euler), "implicit"
// (implicit in the velocity-dependent forces) and "rk4". Springs are spatial tendons (MuJoCo's
// passive stiffness and damping, inside every RK4 stage); other forces are applied as external
// wrenches from the state at the step's start. Contacts: MuJoCo's soft constraints,
// default solref/solimp, pyramidal friction cone (condim 3) with no torsional or rolling
// friction. MuJoCo takes the larger of two geoms' friction, so a scene whose bodies' friction
// differ is written with an explicit <pair> (geometric mean) for every pair of geoms, up to 64
// bodies; beyond that it is refused. MuJoCo 2.2 has no sleeping: every body is always simulated.
// Joints: hinge, slider and a limitless cone_twist are joints of MuJoCo's kinematic tree (exact:
// reduced coordinates), point_to_point and fixed are equalities, distance a tendon; motors and
// closed loops of tree joints are refused. Height fields: an hfield; compounds: a geom per
// part; a triangle mesh is refused (MuJoCo's meshes are convex). CELLPHYS_BENCH_MJCF=FILE
// writes the model there.
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <sstream>
#include <vector>

#include "bench/peers/common_checks.h"
#include "bench/peers/peer.h"

namespace cellphys::bench {
namespace {

// Shortest quaternion turning +z into n.
void z_to(const float n[3], double q[4]) {
  const double len = std::sqrt(double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2]);
  const double x = n[0] / len, y = n[1] / len, z = n[2] / len;
  if (z < -0.999999) {
    q[0] = 0, q[1] = 1, q[2] = 0, q[3] = 0;
    return;
  }
  const double w = 1 + z, ax = -y, ay = x;  // cross(z, n) = (-y, x, 0)
  const double s = std::sqrt(w * w + ax * ax + ay * ay);
  q[0] = w / s, q[1] = ax / s, q[2] = ay / s, q[3] = 0;
}

// MuJoCo's warnings (a full contact buffer, an unstable state) would go to MUJOCO_LOG.TXT in the
// working directory; they are counted instead and shown in the label.
int g_warnings = 0;
void count_warning(const char*) { ++g_warnings; }

class MujocoPeer : public Peer {
 public:
  MujocoPeer(const scene::SceneDesc& scene, const EngineConfig& c) {
    check_forces(scene, "MuJoCo");
    mju_user_warning = count_warning;
    g_warnings = 0;
    const std::string v = c.variant.empty() ? "euler" : c.variant;
    const char* integ = v == "euler" ? "Euler" : v == "implicit" ? "implicit" : v == "rk4" ? "RK4" : nullptr;
    if (!integ) throw std::invalid_argument("mujoco variants: euler, implicit, rk4");
    label_ = "mujoco " + v;
    const double dt = c.dt > 0 ? c.dt : scene.settings.dt;
    const std::vector<BodyInfo> info = body_info(scene);
    forces_ = std::make_unique<ExternalForces>(scene, info, false);

    bool same_friction = true;
    for (const auto& b : scene.bodies) same_friction = same_friction && b.friction == scene.bodies[0].friction;
    const bool pairs = !same_friction;
    if (pairs && scene.bodies.size() > 64)
      throw Unsupported("MuJoCo combines friction by maximum; per-pair geometric means are written only up to 64 bodies");

    std::ostringstream x, assets, world;
    x.precision(9);
    assets.precision(9);
    world.precision(9);
    size_t contacts_guess = 0;
    // Springs as spatial tendons between two sites.
    std::vector<std::string> sites(scene.bodies.size());
    std::ostringstream tendons, world_sites;
    tendons.precision(9);
    world_sites.precision(9);
    for (size_t f = 0; f < scene.forces.size(); ++f) {
      const scene::ForceSpec& fs = scene.forces[f];
      if (fs.type != "spring") continue;
      const int a = body_index(scene, fs.a), b = body_index(scene, fs.b);
      auto site = [&](const char* point, int body, const char* tag) {
        std::ostringstream o;
        o.precision(9);
        o << "<site name=\"s" << f << tag << "\" pos=\"" << param_of(fs.params, point, 0) << " "
          << param_of(fs.params, point, 1) << " " << param_of(fs.params, point, 2) << "\"/>";
        if (body < 0) world_sites << o.str() << "\n";
        else sites[body] += o.str();
      };
      site("point_a", a, "a");
      site("point_b", b, "b");
      tendons << "<spatial stiffness=\"" << param_of(fs.params, "stiffness") << "\" damping=\""
              << param_of(fs.params, "damping") << "\" springlength=\"" << param_of(fs.params, "rest_length")
              << "\"><site site=\"s" << f << "a\"/><site site=\"s" << f << "b\"/></spatial>\n";
    }
    const auto& g = scene.settings.globals.gravity;
    index_.assign(scene.bodies.size(), -1);
    const size_t n = scene.bodies.size();
    std::vector<bool> dynamic(n);
    for (size_t i = 0; i < n; ++i)
      dynamic[i] = !scene.bodies[i].is_static && scene.shapes[info[i].shape].type != spu::ShapeType::plane;

    // Joints. hinge, slider and a free cone_twist are joints of MuJoCo's kinematic tree: the
    // child body nested in its parent (the world for a joint to the world) with a hinge, slide
    // or ball joint at the joint's point in the child's frame; the tree is grown from the world
    // outward, then from the first body not yet in it (with a free joint). A closed loop of such
    // joints is refused. point_to_point is a `connect` equality, fixed a `weld` (the start pose),
    // distance a spatial tendon with a length range.
    const std::vector<JointSpec> js = scene_joints(scene);
    auto in_tree = [](const JointSpec& j) { return j.type == "hinge" || j.type == "slider" || j.type == "cone_twist"; };
    for (const JointSpec& j : js) {
      if (in_tree(j) && j.motor_max > 0)
        throw Unsupported("MuJoCo: its joints have no motor (a velocity actuator needs a gain the scene does not give)");
      if (j.type == "cone_twist" && (j.cone_angle > 0 || j.twist_limited()))
        throw Unsupported("MuJoCo: its ball joint limits the whole turn's angle, not a swing cone and a twist range");
      if (j.type == "cone_twist" && j.spring_k > 0)
        throw Unsupported("MuJoCo: its ball joint's spring pulls toward the start pose, not the aligned pose");
    }
    constexpr int kUnplaced = -3, kFree = -2;
    std::vector<int> parent(n, kUnplaced), via(n, -1);
    std::vector<bool> used(js.size(), false);
    const std::string loop = "MuJoCo: a closed loop of hinge, slider or cone_twist joints (its tree joints cannot close one)";
    for (size_t k = 0; k < js.size(); ++k) {
      if (!in_tree(js[k]) || js[k].b >= 0) continue;
      if (parent[js[k].a] != kUnplaced) throw Unsupported(loop);
      parent[js[k].a] = -1, via[js[k].a] = static_cast<int>(k), used[k] = true;
    }
    for (;;) {
      for (bool grew = true; grew;) {
        grew = false;
        for (size_t k = 0; k < js.size(); ++k) {
          if (used[k] || !in_tree(js[k]) || js[k].b < 0) continue;
          const int a = js[k].a, bb = js[k].b;
          const bool ha = parent[a] != kUnplaced, hb = parent[bb] != kUnplaced;
          if (ha == hb) continue;
          const int child = ha ? bb : a;
          parent[child] = ha ? a : bb, via[child] = static_cast<int>(k), used[k] = grew = true;
        }
      }
      size_t i = 0;
      while (i < n && !(dynamic[i] && parent[i] == kUnplaced)) ++i;
      if (i == n) break;
      parent[i] = kFree;
    }
    for (size_t k = 0; k < js.size(); ++k)
      if (in_tree(js[k]) && !used[k]) throw Unsupported(loop);
    tree_ = false;
    for (size_t i = 0; i < n; ++i) tree_ = tree_ || (dynamic[i] && parent[i] != kFree);

    // Pairs a joint joins make no contacts in cellphys: a tree joint's are filtered as parent
    // and child; the others are excluded.
    std::vector<std::pair<int, int>> joined;
    for (const JointSpec& j : js)
      if (j.b >= 0) joined.push_back({std::min(j.a, j.b), std::max(j.a, j.b)});
    std::ostringstream eq, contact;
    eq.precision(9);
    contact.precision(9);
    for (const JointSpec& j : js) {
      if (in_tree(j)) continue;
      const std::string b1 = "b" + std::to_string(j.a), b2 = j.b >= 0 ? " body2=\"b" + std::to_string(j.b) + "\"" : "";
      if (j.type == "point_to_point") {
        eq << "<connect body1=\"" << b1 << "\"" << b2 << " anchor=\"" << j.pa[0] << " " << j.pa[1] << " " << j.pa[2]
           << "\"/>\n";
      } else if (j.type == "fixed") {
        eq << "<weld body1=\"" << b1 << "\"" << b2 << "/>\n";  // holds the start pose
      } else {  // distance
        const std::string tag = "j" + std::to_string(j.force);
        auto site = [&](const double* p, int body, const char* end) {
          std::ostringstream o;
          o.precision(9);
          o << "<site name=\"" << tag << end << "\" pos=\"" << p[0] << " " << p[1] << " " << p[2] << "\"/>";
          if (body < 0) world_sites << o.str() << "\n";
          else sites[body] += o.str();
        };
        site(j.pa, j.a, "a");
        site(j.pb, j.b, "b");
        tendons << "<spatial name=\"" << tag << "\" stiffness=\"" << j.spring_k << "\" damping=\"" << j.spring_c
                << "\" springlength=\"" << j.spring_rest << "\"";
        // A rod (both bounds equal) is an equality on the tendon's length, which MuJoCo
        // measures from its length at the start; a rope or spacer is a limit on one side.
        if (j.min_length > 0 && j.min_length == j.max_length)
          eq << "<tendon tendon1=\"" << tag << "\" polycoef=\"" << j.max_length - j.length0 << " 0 0 0 0\"/>\n";
        else if (j.min_length > 0 || j.max_length > 0)
          tendons << " limited=\"true\" range=\"" << j.min_length << " " << (j.max_length > 0 ? j.max_length : 1e10)
                  << "\"";
        tendons << "><site site=\"" << tag << "a\"/><site site=\"" << tag << "b\"/></spatial>\n";
      }
      if (j.b >= 0 && !pairs) contact << "<exclude body1=\"" << b1 << "\" body2=\"b" << j.b << "\"/>\n";
    }

    struct TreeJoint {
      int body, joint;
      double sign;
    };
    std::vector<TreeJoint> tree_joints;
    std::vector<std::pair<std::string, std::vector<float>>> elevations;  // each hfield's, in [0, 1]
    std::vector<std::string> body_xml(n);  // a dynamic body's geoms, inertial, joint and sites
    std::vector<std::vector<std::string>> geom_names(n);
    std::vector<std::vector<int>> children(n + 1);  // children[n]: the world's
    for (size_t i = 0; i < n; ++i) {
      const scene::BodySpec& b = scene.bodies[i];
      const ppe::BodyState& st = b.state;
      const BodyInfo& bi = info[i];
      const scene::ShapeSpec& s = scene.shapes[bi.shape];
      const double sc = b.scale;
      const std::string fr = " friction=\"" + num(b.friction) + " 0 0\"" + (pairs ? " contype=\"0\" conaffinity=\"0\"" : "");
      std::ostringstream geom;  // the body's geoms, in its frame
      geom.precision(9);
      bool framed = false;      // a static body written as a jointless body (its geoms at poses in it)
      switch (s.type) {
        case spu::ShapeType::sphere:
        case spu::ShapeType::box:
        case spu::ShapeType::capsule:
        case spu::ShapeType::hull:
          geom << "<geom name=\"g" << i << "\"" << shape_attrs(s, sc, bi.hull_vertices, "m" + std::to_string(i), assets)
               << fr << "/>";
          geom_names[i].push_back("g" + std::to_string(i));
          break;
        case spu::ShapeType::mesh:
          throw Unsupported("MuJoCo: its meshes are convex (the hull of the vertices); a triangle mesh has no equivalent");
        case spu::ShapeType::height_field: {
          // An hfield asset: MuJoCo's grid is centred on the geom, rows along y from -y, columns
          // along x, as cellphys's; it scales the heights to [0, 1] of size[2], so the geom sits
          // at the lowest height. MuJoCo triangulates each cell itself.
          const double rx = 0.5 * (s.columns - 1) * s.spacing[0] * sc, ry = 0.5 * (s.rows - 1) * s.spacing[1] * sc;
          const double lo = sc * *std::min_element(s.heights.begin(), s.heights.end());
          const double hi = sc * *std::max_element(s.heights.begin(), s.heights.end());
          const double top = std::max(hi - lo, 1e-6);
          assets << "<hfield name=\"h" << i << "\" nrow=\"" << s.rows << "\" ncol=\"" << s.columns << "\" size=\"" << rx
                 << " " << ry << " " << top << " " << std::max(1.0, top) << "\"/>\n";
          // MuJoCo 2.2 reads elevations only from files: they are set in the model once loaded.
          std::vector<float> e;
          for (float hgt : s.heights) e.push_back(float((sc * hgt - lo) / top));
          elevations.push_back({"h" + std::to_string(i), std::move(e)});
          geom << "<geom name=\"g" << i << "\" type=\"hfield\" hfield=\"h" << i << "\" pos=\"0 0 " << lo << "\"" << fr << "/>";
          geom_names[i].push_back("g" + std::to_string(i));
          framed = true;
          break;
        }
        case spu::ShapeType::compound:
          // A geom per part at its pose about the compound's centre of mass (cellphys's re-centred parts).
          for (size_t k = 0; k < bi.parts.size(); ++k) {
            const BodyInfo::Part& part = bi.parts[k];
            const std::string gname = "g" + std::to_string(i) + "_" + std::to_string(k);
            const std::string attrs = shape_attrs(scene.shapes[part.shape], part.scale, part.hull_vertices,
                                                  "m" + std::to_string(i) + "_" + std::to_string(k), assets);
            if (attrs.empty()) throw Unsupported("MuJoCo: a compound part that is not convex");
            geom << "<geom name=\"" << gname << "\"" << attrs << pose_xml(part.position, part.orientation) << fr << "/>";
            geom_names[i].push_back(gname);
          }
          framed = true;
          break;
        case spu::ShapeType::plane: {
          double q[4];
          z_to(s.normal, q);
          const double len = std::sqrt(double(s.normal[0]) * s.normal[0] + double(s.normal[1]) * s.normal[1] +
                                       double(s.normal[2]) * s.normal[2]);
          geom << "<geom name=\"g" << i << "\" type=\"plane\" size=\"0 0 1\" pos=\"" << s.normal[0] * s.offset / (len * len)
               << " " << s.normal[1] * s.offset / (len * len) << " " << s.normal[2] * s.offset / (len * len)
               << "\" quat=\"" << q[0] << " " << q[1] << " " << q[2] << " " << q[3] << "\"" << fr << "/>";
          geom_names[i].push_back("g" + std::to_string(i));
          break;
        }
      }
      if (!dynamic[i]) {
        std::string g = geom.str();
        if (framed)
          world << "<body name=\"s" << i << "\"" << pose_xml(st.position, st.orientation) << ">" << g << "</body>\n";
        else if (s.type == spu::ShapeType::plane)
          world << g << "\n";
        else
          world << g.substr(0, g.size() - 2) << pose_xml(st.position, st.orientation) << "/>\n";
        continue;
      }
      contacts_guess += 3;
      std::ostringstream o;
      o.precision(9);
      if (parent[i] == kFree) {
        o << "<freejoint/>";
      } else {
        // The joint in the child's frame; sign: +1 when the child is the joint's b (MuJoCo's
        // coordinate is then cellphys's angle or travel less its start value), -1 when it is a.
        const JointSpec& j = js[via[i]];
        const bool child_b = j.b == static_cast<int>(i);
        const double* p = child_b ? j.pb : j.pa;
        const double* ax = child_b ? j.axis_b : j.axis_a;
        const double sign = child_b ? 1.0 : -1.0;
        const double start = j.type == "hinge" ? j.angle0 : j.travel0;
        o << "<joint type=\"" << (j.type == "hinge" ? "hinge" : j.type == "slider" ? "slide" : "ball") << "\" pos=\""
          << p[0] << " " << p[1] << " " << p[2] << "\"";
        if (j.type != "cone_twist") {
          o << " axis=\"" << ax[0] << " " << ax[1] << " " << ax[2] << "\"";
          if (j.limited()) {
            const double lo = sign * (j.lower - start), hi = sign * (j.upper - start);
            o << " limited=\"true\" range=\"" << std::min(lo, hi) << " " << std::max(lo, hi) << "\"";
          }
          if (j.spring_k > 0) o << " stiffness=\"" << j.spring_k << "\" springref=\"" << sign * (j.spring_rest - start) << "\"";
        }
        if (j.spring_c > 0) o << " damping=\"" << j.spring_c << "\"";
        o << "/>";
        tree_joints.push_back({static_cast<int>(i), via[i], sign});
      }
      o << "<inertial pos=\"0 0 0\" mass=\"" << bi.mass << "\" fullinertia=\"" << bi.inertia[0] << " " << bi.inertia[1]
        << " " << bi.inertia[2] << " " << bi.inertia[3] << " " << bi.inertia[4] << " " << bi.inertia[5] << "\"/>"
        << geom.str() << sites[i];
      body_xml[i] = o.str();
      children[parent[i] >= 0 ? parent[i] : n].push_back(static_cast<int>(i));
    }
    // The bodies, nested: a child's pose relative to its parent's.
    std::function<void(int, int)> emit = [&](int i, int par) {
      const ppe::BodyState& st = scene.bodies[i].state;
      double p[3], q[4];
      pose_of(st, p, q);
      if (par >= 0) {
        double pp[3], pq[4], d[3], rel[4];
        pose_of(scene.bodies[par].state, pp, pq);
        for (int k = 0; k < 3; ++k) d[k] = p[k] - pp[k];
        quat_rotate_inv(pq, d, p);
        const double c[4] = {pq[0], -pq[1], -pq[2], -pq[3]};
        quat_mul(c, q, rel);
        std::copy(rel, rel + 4, q);
      }
      world << "<body name=\"b" << i << "\"" << pose_xml(p, q) << ">" << body_xml[i];
      for (int c : children[i]) emit(c, i);
      world << "</body>\n";
    };
    for (int i : children[n]) emit(i, -1);
    if (pairs) {
      for (size_t i = 0; i < n; ++i)
        for (size_t j = i + 1; j < n; ++j) {
          if (!dynamic[i] && !dynamic[j]) continue;
          if (std::find(joined.begin(), joined.end(), std::make_pair(int(i), int(j))) != joined.end()) continue;
          const double mu = std::sqrt(double(scene.bodies[i].friction) * scene.bodies[j].friction);
          for (const std::string& g1 : geom_names[i])
            for (const std::string& g2 : geom_names[j])
              contact << "<pair geom1=\"" << g1 << "\" geom2=\"" << g2 << "\" condim=\"3\" friction=\"" << mu << " " << mu
                      << " 0 0 0\"/>\n";
        }
    }
    // Resting contacts: about 2.5 a body in a sparse world, 6 in a pile.
    const size_t nconmax = std::max<size_t>(1000, contacts_guess + 100);
    const size_t njmax = 4 * nconmax + 6 * scene.forces.size();  // pyramidal cone: 4 rows a contact
    x << "<mujoco model=\"scene\">\n<compiler angle=\"radian\" inertiafromgeom=\"false\"/>\n"
      << "<option timestep=\"" << dt << "\" gravity=\"" << g[0] << " " << g[1] << " " << g[2] << "\" integrator=\""
      << integ << "\" jacobian=\"sparse\"/>\n<size nconmax=\"" << nconmax << "\" njmax=\"" << njmax << "\"/>\n"
      << "<asset>\n" << assets.str() << "</asset>\n<worldbody>\n" << world_sites.str() << world.str() << "</worldbody>\n"
      << "<tendon>\n" << tendons.str() << "</tendon>\n"
      << "<equality>\n" << eq.str() << "</equality>\n<contact>\n" << contact.str() << "</contact>\n</mujoco>\n";
    const std::string xml = x.str();
    if (const char* dump = std::getenv("CELLPHYS_BENCH_MJCF")) {  // the model as written, for a look
      if (FILE* out = std::fopen(dump, "w")) std::fputs(xml.c_str(), out), std::fclose(out);
    }

    auto vfs = std::make_unique<mjVFS>();
    mj_defaultVFS(vfs.get());
    if (mj_makeEmptyFileVFS(vfs.get(), "scene.xml", static_cast<int>(xml.size())) != 0)
      throw std::runtime_error("MuJoCo VFS full");
    const int f = mj_findFileVFS(vfs.get(), "scene.xml");
    std::memcpy(vfs->filedata[f], xml.data(), xml.size());
    char err[1000] = "";
    model_ = mj_loadXML("scene.xml", vfs.get(), err, sizeof err);
    mj_deleteVFS(vfs.get());
    if (!model_ && std::strstr(err, "could not create mjData"))
      throw Unsupported("MuJoCo 2.2.2 could not allocate its dense constraint arrays (njmax " + std::to_string(njmax) +
                        " rows: about " + std::to_string(int(8e-9 * double(njmax) * double(njmax + 6 * contacts_guess / 3) + 0.5)) +
                        " GB)");
    if (!model_) throw std::runtime_error(std::string("MuJoCo refused the model: ") + err);
    for (const auto& [hname, e] : elevations) {
      const int id = mj_name2id(model_, mjOBJ_HFIELD, hname.c_str());
      std::copy(e.begin(), e.end(), model_->hfield_data + model_->hfield_adr[id]);
    }
    data_ = mj_makeData(model_);
    if (!data_) {
      // MuJoCo 2.2 preallocates dense njmax x nv and njmax x njmax constraint arrays.
      char why[300];
      std::snprintf(why, sizeof why,
                    "MuJoCo 2.2.2 could not allocate its dense constraint arrays (njmax %zu x nv %d, about %.1f GB)",
                    njmax, model_->nv, 8e-9 * double(njmax) * double(njmax + model_->nv));
      throw Unsupported(why);
    }
    for (size_t i = 0; i < n; ++i)
      if (dynamic[i]) index_[i] = mj_name2id(model_, mjOBJ_BODY, ("b" + std::to_string(i)).c_str());
    for (size_t i = 0; i < n; ++i) {
      if (index_[i] < 0 || parent[i] != kFree) continue;
      const ppe::BodyState& b = scene.bodies[i].state;
      const int dof = model_->jnt_dofadr[model_->body_jntadr[index_[i]]];
      double w[3] = {b.angular_velocity[0], b.angular_velocity[1], b.angular_velocity[2]}, wb[3], p[3], q[4];
      pose_of(b, p, q);
      quat_rotate_inv(q, w, wb);
      for (int k = 0; k < 3; ++k) data_->qvel[dof + k] = b.velocity[k], data_->qvel[dof + 3 + k] = wb[k];
    }
    // A tree joint's speed from the scene's start velocities: the hinge's or slider's rate
    // (b's from a's, along a's axis), the ball's relative turn in the child's frame.
    for (const TreeJoint& t : tree_joints) {
      const JointSpec& j = js[t.joint];
      const int dof = model_->jnt_dofadr[model_->body_jntadr[index_[t.body]]];
      double va[3], vb[3] = {}, wa[3], wb[3] = {}, rel[3];
      point_velocity(scene.bodies[j.a].state, j.wpb, va, wa);
      if (j.b >= 0) point_velocity(scene.bodies[j.b].state, j.wpb, vb, wb);
      if (j.type == "cone_twist") {
        double p[3], q[4];
        pose_of(scene.bodies[t.body].state, p, q);
        for (int k = 0; k < 3; ++k) rel[k] = t.sign * (wb[k] - wa[k]);
        double local[3];
        quat_rotate_inv(q, rel, local);
        for (int k = 0; k < 3; ++k) data_->qvel[dof + k] = local[k];
        continue;
      }
      const double* u = j.type == "hinge" ? wa : va;
      const double* v = j.type == "hinge" ? wb : vb;
      double rate = 0;
      for (int k = 0; k < 3; ++k) rate += (v[k] - u[k]) * j.wna[k];
      data_->qvel[dof] = t.sign * rate;
    }
    if (tree_) mj_forward(model_, data_);
    static_state_.resize(scene.bodies.size());
    for (size_t i = 0; i < scene.bodies.size(); ++i) {
      State& s = static_state_[i];
      s = State{};
      for (int k = 0; k < 3; ++k) s.p[k] = scene.bodies[i].state.position[k];
      for (int k = 0; k < 4; ++k) s.q[k] = scene.bodies[i].state.orientation[k];
    }
    states_.resize(scene.bodies.size());
  }
  ~MujocoPeer() override {
    if (data_) mj_deleteData(data_);
    if (model_) mj_deleteModel(model_);
  }
  void step() override {
    if (!forces_->empty()) {
      for (size_t i = 0; i < index_.size(); ++i) states_[i] = state(i);
      forces_->evaluate(states_, wrench_);
      for (size_t i = 0; i < index_.size(); ++i)
        if (index_[i] >= 0)
          for (int k = 0; k < 6; ++k) data_->xfrc_applied[6 * index_[i] + k] = wrench_[6 * i + k];
    }
    const long before = warnings();
    mj_step(model_, data_);
    if (tree_) {  // bodies inside a tree are read from their frames: bring them to the new state
      mj_kinematics(model_, data_);
      mj_comPos(model_, data_);
      mj_comVel(model_, data_);
    }
    failed_ = warnings() > before;
  }
  State state(size_t i) const override {
    if (index_[i] < 0) return static_state_[i];
    const int j = model_->body_jntadr[index_[i]];
    if (model_->jnt_type[j] != mjJNT_FREE) {
      State s;
      const int id = index_[i];
      mjtNum vel[6];
      mj_objectVelocity(model_, data_, mjOBJ_BODY, id, vel, 0);  // angular, linear; world axes
      for (int k = 0; k < 3; ++k) s.p[k] = data_->xpos[3 * id + k], s.w[k] = vel[k], s.v[k] = vel[3 + k];
      for (int k = 0; k < 4; ++k) s.q[k] = data_->xquat[4 * id + k];
      return s;
    }
    const mjtNum* qp = data_->qpos + model_->jnt_qposadr[j];
    const mjtNum* qv = data_->qvel + model_->jnt_dofadr[j];
    State s;
    for (int k = 0; k < 3; ++k) s.p[k] = qp[k], s.v[k] = qv[k];
    for (int k = 0; k < 4; ++k) s.q[k] = qp[3 + k];
    const double wb[3] = {qv[3], qv[4], qv[5]};
    quat_rotate(s.q, wb, s.w);
    return s;
  }
  long active_bodies() const override {
    long n = 0;
    for (int i : index_) n += i >= 0;
    return n;
  }
  int last_step_failed() const override { return failed_; }
  std::string label() const override {
    return g_warnings ? label_ + " (" + std::to_string(g_warnings) + " MuJoCo warnings)" : label_;
  }

 private:
  // MuJoCo counts every warning in mjData (and reports only the first of a kind).
  long warnings() const {
    long n = 0;
    for (int k = 0; k < mjNWARNING; ++k) n += data_->warning[k].number;
    return n;
  }
  template <class T, class U>
  static std::string pose_xml(const T* p, const U* q) {
    return " pos=\"" + num(p[0]) + " " + num(p[1]) + " " + num(p[2]) + "\" quat=\"" + num(q[0]) + " " + num(q[1]) +
           " " + num(q[2]) + " " + num(q[3]) + "\"";
  }
  static void pose_of(const ppe::BodyState& b, double p[3], double q[4]) {
    double len = 0;
    for (int k = 0; k < 4; ++k) q[k] = b.orientation[k], len += q[k] * q[k];
    len = std::sqrt(len);
    for (int k = 0; k < 4; ++k) q[k] /= len;
    for (int k = 0; k < 3; ++k) p[k] = b.position[k];
  }
  static void quat_mul(const double a[4], const double b[4], double o[4]) {
    o[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    o[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    o[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    o[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
  }
  // The velocity of a body's point x (world) and its angular velocity, at the scene's start.
  static void point_velocity(const ppe::BodyState& b, const double x[3], double v[3], double w[3]) {
    double r[3];
    for (int k = 0; k < 3; ++k) r[k] = x[k] - b.position[k], w[k] = b.angular_velocity[k];
    v[0] = b.velocity[0] + w[1] * r[2] - w[2] * r[1];
    v[1] = b.velocity[1] + w[2] * r[0] - w[0] * r[2];
    v[2] = b.velocity[2] + w[0] * r[1] - w[1] * r[0];
  }
  // A convex shape's type and size attributes at a scale (a hull: a mesh asset of its cellphys
  // vertices, already scaled, added to assets); "" for the others.
  static std::string shape_attrs(const scene::ShapeSpec& s, double sc, const std::vector<double>& hull,
                                 const std::string& mesh, std::ostringstream& assets) {
    switch (s.type) {
      case spu::ShapeType::sphere: return " type=\"sphere\" size=\"" + num(s.radius * sc) + "\"";
      case spu::ShapeType::box:
        return " type=\"box\" size=\"" + num(s.half_extents[0] * sc) + " " + num(s.half_extents[1] * sc) + " " +
               num(s.half_extents[2] * sc) + "\"";
      case spu::ShapeType::capsule:
        return " type=\"capsule\" size=\"" + num(s.radius * sc) + " " + num(s.half_height * sc) + "\"";
      case spu::ShapeType::hull:
        assets << "<mesh name=\"" << mesh << "\" vertex=\"";
        for (double p : hull) assets << p << " ";
        assets << "\"/>\n";
        return " type=\"mesh\" mesh=\"" + mesh + "\"";
      default: return "";
    }
  }
  static std::string num(double v) {
    std::ostringstream o;
    o.precision(9);
    o << v;
    return o.str();
  }
  std::unique_ptr<ExternalForces> forces_;
  std::string label_;
  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  std::vector<int> index_;  // MuJoCo body id of each scene body, -1 for static ones
  bool tree_ = false;       // some body sits in a kinematic tree (not on a free joint)
  std::vector<State> static_state_, states_;
  std::vector<double> wrench_;
  int failed_ = 0;
};

}  // namespace

std::unique_ptr<Peer> make_mujoco(const scene::SceneDesc& scene, const EngineConfig& c) {
  return std::make_unique<MujocoPeer>(scene, c);
}

}  // namespace cellphys::bench
