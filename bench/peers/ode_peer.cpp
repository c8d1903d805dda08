// ODE 0.16 (double precision): "step" is dWorldStep (the direct, Dantzig LCP solver), "quickstep"
// dWorldQuickStep (iterative SOR, 20 iterations unless given). Contacts: up to 8 points a pair,
// dContactApprox1 friction with the geometric mean of the bodies' coefficients, ODE's default
// ERP and CFM, a 1 mm surface layer. Hulls: dCreateConvex on the cellphys hull's planes and
// faces. Sleeping maps onto ODE's auto-disable. Joints: ball, hinge, slider, fixed and (for a
// rod) double-ball joints with ODE's default ERP and CFM; a joint spring or damper, a rope or
// spacer and a cone-twist are refused.
#include <ode/ode.h>

#include <cmath>
#include <cstdarg>
#include <memory>
#include <vector>

#include "bench/peers/common_checks.h"
#include "bench/peers/peer.h"

namespace cellphys::bench {
namespace {

// ODE reports LCP trouble through its message handler; the bench counts nothing and stays quiet.
void quiet(int, const char*, va_list) {}

struct OdeInit {
  OdeInit() {
    dInitODE2(0);
    dSetMessageHandler(quiet);
  }
};

class OdePeer : public Peer {
 public:
  OdePeer(const scene::SceneDesc& scene, const EngineConfig& c) {
    static OdeInit init;
    check_forces(scene, "ODE");
    quick_ = c.variant == "quickstep";
    if (!c.variant.empty() && c.variant != "step" && !quick_) throw std::invalid_argument("ode variants: step, quickstep");
    dt_ = c.dt > 0 ? c.dt : scene.settings.dt;
    const std::vector<BodyInfo> info = body_info(scene);
    forces_ = std::make_unique<ExternalForces>(scene, info);
    world_ = dWorldCreate();
    space_ = dHashSpaceCreate(nullptr);
    contacts_ = dJointGroupCreate(0);
    const auto& g = scene.settings.globals.gravity;
    dWorldSetGravity(world_, g[0], g[1], g[2]);
    dWorldSetContactSurfaceLayer(world_, 0.001);
    iterations_ = c.iterations > 0 ? c.iterations : 20;
    dWorldSetQuickStepNumIterations(world_, iterations_);
    label_ = quick_ ? "ode quickstep (" + std::to_string(iterations_) + " iterations)" : "ode step";
    if (scene.settings.sleeping) {
      dWorldSetAutoDisableFlag(world_, 1);
      dWorldSetAutoDisableLinearThreshold(world_, scene.settings.sleep_linear);
      dWorldSetAutoDisableAngularThreshold(world_, scene.settings.sleep_angular);
      dWorldSetAutoDisableTime(world_, scene.settings.sleep_time);
      dWorldSetAutoDisableSteps(world_, std::max(1, int(scene.settings.sleep_time / dt_)));
    }
    friction_.resize(scene.bodies.size());
    bodies_.assign(scene.bodies.size(), nullptr);
    geoms_.resize(scene.bodies.size());
    for (size_t i = 0; i < scene.bodies.size(); ++i) {
      const scene::BodySpec& b = scene.bodies[i];
      const ppe::BodyState& st = b.state;
      const BodyInfo& bi = info[i];
      const scene::ShapeSpec& s = scene.shapes[bi.shape];
      const double sc = b.scale;
      friction_[i] = b.friction;
      dGeomID geom = nullptr;
      switch (s.type) {
        case spu::ShapeType::sphere: geom = dCreateSphere(space_, s.radius * sc); break;
        case spu::ShapeType::box:
          geom = dCreateBox(space_, 2 * s.half_extents[0] * sc, 2 * s.half_extents[1] * sc, 2 * s.half_extents[2] * sc);
          break;
        case spu::ShapeType::capsule: geom = dCreateCapsule(space_, s.radius * sc, 2 * s.half_height * sc); break;
        case spu::ShapeType::hull: {
          hull_points_.push_back(std::make_unique<std::vector<dReal>>(bi.hull_vertices.begin(), bi.hull_vertices.end()));
          hull_planes_.push_back(std::make_unique<std::vector<dReal>>(bi.hull_planes.begin(), bi.hull_planes.end()));
          hull_faces_.push_back(std::make_unique<std::vector<unsigned>>(bi.hull_faces.begin(), bi.hull_faces.end()));
          geom = dCreateConvex(space_, hull_planes_.back()->data(), unsigned(bi.hull_planes.size() / 4),
                               hull_points_.back()->data(), unsigned(bi.hull_vertices.size() / 3),
                               hull_faces_.back()->data());
          break;
        }
        case spu::ShapeType::mesh:
        case spu::ShapeType::height_field:
          throw Unsupported("ODE: meshes and height fields are not mapped to its triangle shapes yet");
        case spu::ShapeType::compound:
          throw Unsupported("ODE: compound bodies are not mapped to its compound shapes yet");
        case spu::ShapeType::plane: geom = dCreatePlane(space_, s.normal[0], s.normal[1], s.normal[2], s.offset); break;
      }
      geoms_[i] = geom;
      dGeomSetData(geom, reinterpret_cast<void*>(i));
      const dQuaternion q = {st.orientation[0], st.orientation[1], st.orientation[2], st.orientation[3]};
      if (s.type == spu::ShapeType::plane) continue;
      if (b.is_static) {
        dGeomSetPosition(geom, st.position[0], st.position[1], st.position[2]);
        dGeomSetQuaternion(geom, q);
        continue;
      }
      dBodyID body = dBodyCreate(world_);
      dMass m;
      dMassSetParameters(&m, bi.mass, 0, 0, 0, bi.inertia[0], bi.inertia[1], bi.inertia[2], bi.inertia[3],
                         bi.inertia[4], bi.inertia[5]);
      dBodySetMass(body, &m);
      dBodySetPosition(body, st.position[0], st.position[1], st.position[2]);
      dBodySetQuaternion(body, q);
      dBodySetLinearVel(body, st.velocity[0], st.velocity[1], st.velocity[2]);
      dBodySetAngularVel(body, st.angular_velocity[0], st.angular_velocity[1], st.angular_velocity[2]);
      dGeomSetBody(geom, body);
      bodies_[i] = body;
    }
    for (const JointSpec& j : scene_joints(scene)) {
      dBodyID ba = bodies_[j.a], bb = j.b < 0 ? nullptr : bodies_[j.b];
      const char* lacks = j.type == "hinge" || j.type == "slider" ? "a spring or damper" : nullptr;
      if (lacks && (j.spring_k > 0 || j.spring_c > 0))
        throw Unsupported("ODE: its " + j.type + " joint has no spring or damper (the scene's has spring_stiffness "
                          "or spring_damping)");
      dJointID jt = nullptr;
      // ODE measures hinge angles and slider positions of body 1 (a) from body 2 (b), zero at
      // the pose the joint is set up in: cellphys's angle and travel less their start values,
      // negated. Limits and motor speeds are turned the same way.
      if (j.type == "point_to_point") {
        jt = dJointCreateBall(world_, nullptr);
        dJointAttach(jt, ba, bb);
        dJointSetBallAnchor(jt, j.wpa[0], j.wpa[1], j.wpa[2]);
      } else if (j.type == "hinge") {
        jt = dJointCreateHinge(world_, nullptr);
        dJointAttach(jt, ba, bb);
        dJointSetHingeAnchor(jt, j.wpa[0], j.wpa[1], j.wpa[2]);
        dJointSetHingeAxis(jt, j.wna[0], j.wna[1], j.wna[2]);
        if (j.limited()) {
          const double lo = j.angle0 - j.upper, hi = j.angle0 - j.lower;
          if (lo < -M_PI || hi > M_PI)
            throw Unsupported("ODE: hinge stops must lie in [-pi, pi] from the start pose");
          dJointSetHingeParam(jt, dParamLoStop, lo);
          dJointSetHingeParam(jt, dParamHiStop, hi);
        }
        if (j.motor_max > 0) {
          dJointSetHingeParam(jt, dParamVel, -j.motor_speed);
          dJointSetHingeParam(jt, dParamFMax, j.motor_max);
        }
      } else if (j.type == "slider") {
        jt = dJointCreateSlider(world_, nullptr);
        dJointAttach(jt, ba, bb);
        dJointSetSliderAxis(jt, j.wna[0], j.wna[1], j.wna[2]);
        if (j.limited()) {
          dJointSetSliderParam(jt, dParamLoStop, j.travel0 - j.upper);
          dJointSetSliderParam(jt, dParamHiStop, j.travel0 - j.lower);
        }
        if (j.motor_max > 0) {
          dJointSetSliderParam(jt, dParamVel, -j.motor_speed);
          dJointSetSliderParam(jt, dParamFMax, j.motor_max);
        }
      } else if (j.type == "fixed") {
        jt = dJointCreateFixed(world_, nullptr);
        dJointAttach(jt, ba, bb);
        dJointSetFixed(jt);  // holds the start pose
      } else if (j.type == "distance") {
        // dJointCreateDBall holds two anchors at a fixed distance: a rod (min_length =
        // max_length); a rope or a spacer is one-sided, which ODE has no joint for.
        if (!(j.max_length > 0 && j.min_length == j.max_length))
          throw Unsupported("ODE: a distance joint maps only as a rod (min_length = max_length) onto dJointCreateDBall; "
                            "ODE has no one-sided rope or spacer joint");
        if (j.spring_k > 0 || j.spring_c > 0)
          throw Unsupported("ODE: its double-ball joint has no spring or damper");
        jt = dJointCreateDBall(world_, nullptr);
        dJointAttach(jt, ba, bb);
        dJointSetDBallAnchor1(jt, j.wpa[0], j.wpa[1], j.wpa[2]);
        dJointSetDBallAnchor2(jt, j.wpb[0], j.wpb[1], j.wpb[2]);
        dJointSetDBallDistance(jt, j.max_length);
      } else {
        throw Unsupported("ODE: no cone-twist joint (a ball joint with an angular motor's Euler-angle stops "
                          "is not the same cone) is mapped");
      }
    }
    states_.resize(scene.bodies.size());
  }
  ~OdePeer() override {
    dJointGroupDestroy(contacts_);
    dSpaceDestroy(space_);
    dWorldDestroy(world_);
  }
  void step() override {
    if (!forces_->empty()) {
      for (size_t i = 0; i < bodies_.size(); ++i) states_[i] = state(i);
      forces_->evaluate(states_, wrench_);
      for (size_t i = 0; i < bodies_.size(); ++i) {
        if (!bodies_[i]) continue;
        const double* f = &wrench_[6 * i];
        dBodyAddForce(bodies_[i], f[0], f[1], f[2]);
        dBodyAddTorque(bodies_[i], f[3], f[4], f[5]);
      }
    }
    dSpaceCollide(space_, this, &OdePeer::near);
    if (quick_)
      dWorldQuickStep(world_, dt_);
    else
      dWorldStep(world_, dt_);
    dJointGroupEmpty(contacts_);
  }
  State state(size_t i) const override {
    State s{};
    dBodyID b = bodies_[i];
    if (!b) {
      if (dGeomGetClass(geoms_[i]) != dPlaneClass) {
        const dReal* p = dGeomGetPosition(geoms_[i]);
        dQuaternion q;
        dGeomGetQuaternion(geoms_[i], q);
        for (int k = 0; k < 3; ++k) s.p[k] = p[k];
        for (int k = 0; k < 4; ++k) s.q[k] = q[k];
      } else {
        s.q[0] = 1;
      }
      return s;
    }
    const dReal *p = dBodyGetPosition(b), *q = dBodyGetQuaternion(b), *v = dBodyGetLinearVel(b),
                *w = dBodyGetAngularVel(b);
    for (int k = 0; k < 3; ++k) s.p[k] = p[k], s.v[k] = v[k], s.w[k] = w[k];
    for (int k = 0; k < 4; ++k) s.q[k] = q[k];
    return s;
  }
  long active_bodies() const override {
    long n = 0;
    for (dBodyID b : bodies_) n += b && dBodyIsEnabled(b) ? 1 : 0;
    return n;
  }
  double last_iterations() const override { return quick_ ? iterations_ : -1; }
  std::string label() const override { return label_; }

 private:
  static void near(void* data, dGeomID o1, dGeomID o2) {
    OdePeer& self = *static_cast<OdePeer*>(data);
    dBodyID b1 = dGeomGetBody(o1), b2 = dGeomGetBody(o2);
    if (!b1 && !b2) return;
    const bool e1 = b1 && dBodyIsEnabled(b1), e2 = b2 && dBodyIsEnabled(b2);
    if (!e1 && !e2) return;
    if (b1 && b2 && dAreConnectedExcluding(b1, b2, dJointTypeContact)) return;
    dContact contact[8];
    const int n = dCollide(o1, o2, 8, &contact[0].geom, sizeof(dContact));
    if (n <= 0) return;
    const size_t i1 = reinterpret_cast<size_t>(dGeomGetData(o1)), i2 = reinterpret_cast<size_t>(dGeomGetData(o2));
    const double mu = std::sqrt(self.friction_[i1] * self.friction_[i2]);
    for (int k = 0; k < n; ++k) {
      contact[k].surface.mode = dContactApprox1;
      contact[k].surface.mu = mu;
      dJointID j = dJointCreateContact(self.world_, self.contacts_, &contact[k]);
      dJointAttach(j, b1, b2);
    }
  }

  std::unique_ptr<ExternalForces> forces_;
  bool quick_ = false;
  double dt_ = 0;
  int iterations_ = 20;
  std::string label_;
  dWorldID world_ = nullptr;
  dSpaceID space_ = nullptr;
  dJointGroupID contacts_ = nullptr;
  std::vector<double> friction_;
  std::vector<dBodyID> bodies_;
  std::vector<dGeomID> geoms_;
  std::vector<std::unique_ptr<std::vector<dReal>>> hull_points_, hull_planes_;
  std::vector<std::unique_ptr<std::vector<unsigned>>> hull_faces_;
  std::vector<State> states_;
  std::vector<double> wrench_;
};

}  // namespace

std::unique_ptr<Peer> make_ode(const scene::SceneDesc& scene, const EngineConfig& c) {
  return std::make_unique<OdePeer>(scene, c);
}

}  // namespace cellphys::bench
