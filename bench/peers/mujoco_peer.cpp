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
#include <mujoco/mujoco.h>

#include <cmath>
#include <cstdio>
#include <cstring>
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
    int next_body = 1;
    for (size_t i = 0; i < scene.bodies.size(); ++i) {
      const scene::BodySpec& b = scene.bodies[i];
      const ppe::BodyState& st = b.state;
      const BodyInfo& bi = info[i];
      const scene::ShapeSpec& s = scene.shapes[bi.shape];
      const double sc = b.scale;
      std::ostringstream geom;
      geom.precision(9);
      geom << "<geom name=\"g" << i << "\"";
      switch (s.type) {
        case spu::ShapeType::sphere: geom << " type=\"sphere\" size=\"" << s.radius * sc << "\""; break;
        case spu::ShapeType::box:
          geom << " type=\"box\" size=\"" << s.half_extents[0] * sc << " " << s.half_extents[1] * sc << " "
               << s.half_extents[2] * sc << "\"";
          break;
        case spu::ShapeType::capsule:
          geom << " type=\"capsule\" size=\"" << s.radius * sc << " " << s.half_height * sc << "\"";
          break;
        case spu::ShapeType::hull: {
          assets << "<mesh name=\"m" << i << "\" vertex=\"";
          for (double p : bi.hull_vertices) assets << p << " ";
          assets << "\"/>\n";
          geom << " type=\"mesh\" mesh=\"m" << i << "\"";
          break;
        }
        case spu::ShapeType::mesh:
        case spu::ShapeType::height_field:
          throw Unsupported("MuJoCo: meshes and height fields are not mapped to its triangle shapes yet");
        case spu::ShapeType::compound:
          throw Unsupported("MuJoCo: compound bodies are not mapped to its compound shapes yet");
        case spu::ShapeType::plane: {
          double q[4];
          z_to(s.normal, q);
          const double len = std::sqrt(double(s.normal[0]) * s.normal[0] + double(s.normal[1]) * s.normal[1] +
                                       double(s.normal[2]) * s.normal[2]);
          geom << " type=\"plane\" size=\"0 0 1\" pos=\"" << s.normal[0] * s.offset / (len * len) << " "
               << s.normal[1] * s.offset / (len * len) << " " << s.normal[2] * s.offset / (len * len) << "\" quat=\""
               << q[0] << " " << q[1] << " " << q[2] << " " << q[3] << "\"";
          break;
        }
      }
      geom << " friction=\"" << b.friction << " 0 0\"";
      if (pairs) geom << " contype=\"0\" conaffinity=\"0\"";
      const std::string pose = " pos=\"" + num(st.position[0]) + " " + num(st.position[1]) + " " + num(st.position[2]) +
                               "\" quat=\"" + num(st.orientation[0]) + " " + num(st.orientation[1]) + " " +
                               num(st.orientation[2]) + " " + num(st.orientation[3]) + "\"";
      if (b.is_static || s.type == spu::ShapeType::plane) {
        if (s.type == spu::ShapeType::plane)
          world << geom.str() << "/>\n";
        else
          world << geom.str() << pose << "/>\n";
        continue;
      }
      index_[i] = next_body++;
      contacts_guess += 3;
      world << "<body name=\"b" << i << "\"" << pose << "><freejoint/><inertial pos=\"0 0 0\" mass=\"" << bi.mass
            << "\" fullinertia=\"" << bi.inertia[0] << " " << bi.inertia[1] << " " << bi.inertia[2] << " "
            << bi.inertia[3] << " " << bi.inertia[4] << " " << bi.inertia[5] << "\"/>" << geom.str() << "/>" << sites[i]
            << "</body>\n";
    }
    std::ostringstream eq, contact;
    for (const scene::ForceSpec& f : scene.forces) {
      if (f.type != "point_to_point") continue;
      const int a = body_index(scene, f.a), bb = body_index(scene, f.b);
      if (index_[a] < 0) throw Unsupported("MuJoCo: a joint on a static body");
      eq << "<connect body1=\"b" << a << "\"" << (bb >= 0 ? " body2=\"b" + std::to_string(bb) + "\"" : std::string())
         << " anchor=\"" << param_of(f.params, "point_a", 0) << " " << param_of(f.params, "point_a", 1) << " "
         << param_of(f.params, "point_a", 2) << "\"/>\n";
    }
    if (pairs) {
      for (size_t i = 0; i < scene.bodies.size(); ++i)
        for (size_t j = i + 1; j < scene.bodies.size(); ++j) {
          if (index_[i] < 0 && index_[j] < 0) continue;
          const double mu = std::sqrt(double(scene.bodies[i].friction) * scene.bodies[j].friction);
          contact << "<pair geom1=\"g" << i << "\" geom2=\"g" << j << "\" condim=\"3\" friction=\"" << mu << " " << mu
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
    data_ = mj_makeData(model_);
    if (!data_) {
      // MuJoCo 2.2 preallocates dense njmax x nv and njmax x njmax constraint arrays.
      char why[300];
      std::snprintf(why, sizeof why,
                    "MuJoCo 2.2.2 could not allocate its dense constraint arrays (njmax %zu x nv %d, about %.1f GB)",
                    njmax, model_->nv, 8e-9 * double(njmax) * double(njmax + model_->nv));
      throw Unsupported(why);
    }
    for (size_t i = 0; i < scene.bodies.size(); ++i) {
      if (index_[i] < 0) continue;
      const ppe::BodyState& b = scene.bodies[i].state;
      const int dof = model_->jnt_dofadr[model_->body_jntadr[index_[i]]];
      double w[3] = {b.angular_velocity[0], b.angular_velocity[1], b.angular_velocity[2]}, wb[3];
      double q[4] = {b.orientation[0], b.orientation[1], b.orientation[2], b.orientation[3]};
      const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      for (double& e : q) e /= n;
      quat_rotate_inv(q, w, wb);
      for (int k = 0; k < 3; ++k) data_->qvel[dof + k] = b.velocity[k], data_->qvel[dof + 3 + k] = wb[k];
    }
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
    failed_ = warnings() > before;
  }
  State state(size_t i) const override {
    if (index_[i] < 0) return static_state_[i];
    const int j = model_->body_jntadr[index_[i]];
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
  std::vector<State> static_state_, states_;
  std::vector<double> wrench_;
  int failed_ = 0;
};

}  // namespace

std::unique_ptr<Peer> make_mujoco(const scene::SceneDesc& scene, const EngineConfig& c) {
  return std::make_unique<MujocoPeer>(scene, c);
}

}  // namespace cellphys::bench
