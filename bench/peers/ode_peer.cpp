// ODE 0.16 (double precision): "step" is dWorldStep (the direct, Dantzig LCP solver), "quickstep"
// dWorldQuickStep (iterative SOR, 20 iterations unless given). Contacts: up to 8 points a pair,
// dContactApprox1 friction with the geometric mean of the bodies' coefficients, ODE's default
// ERP and CFM, a 1 mm surface layer. Hulls: dCreateConvex on the cellphys hull's planes and
// faces. Sleeping maps onto ODE's auto-disable. Joints: ball, hinge, slider, fixed and (for a
// rod) double-ball joints with ODE's default ERP and CFM; a joint spring or damper, a rope or
// spacer and a cone-twist are refused. Meshes and height fields: the cellphys triangles in a
// static dCreateTriMesh (ODE here has no libccd, so a scene with both triangles and a dynamic
// hull is refused); compounds: a geom per part on the one body, at the part's offset.
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
  // A convex geom at a scale in the space (a hull from its cellphys planes and faces, already
  // scaled); nullptr for the others.
  dGeomID convex(const scene::ShapeSpec& s, double sc, const std::vector<double>& vertices,
                 const std::vector<double>& planes, const std::vector<int>& faces) {
    switch (s.type) {
      case spu::ShapeType::sphere: return dCreateSphere(space_, s.radius * sc);
      case spu::ShapeType::box:
        return dCreateBox(space_, 2 * s.half_extents[0] * sc, 2 * s.half_extents[1] * sc, 2 * s.half_extents[2] * sc);
      case spu::ShapeType::capsule: return dCreateCapsule(space_, s.radius * sc, 2 * s.half_height * sc);
      case spu::ShapeType::hull:
        hull_points_.push_back(std::make_unique<std::vector<dReal>>(vertices.begin(), vertices.end()));
        hull_planes_.push_back(std::make_unique<std::vector<dReal>>(planes.begin(), planes.end()));
        hull_faces_.push_back(std::make_unique<std::vector<unsigned>>(faces.begin(), faces.end()));
        return dCreateConvex(space_, hull_planes_.back()->data(), unsigned(planes.size() / 4),
                             hull_points_.back()->data(), unsigned(vertices.size() / 3), hull_faces_.back()->data());
      default: return nullptr;
    }
  }
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
    bool has_mesh = false, has_hull = false;
    for (size_t i = 0; i < scene.bodies.size(); ++i) {
      const scene::ShapeSpec& s = scene.shapes[info[i].shape];
      has_mesh = has_mesh || s.type == spu::ShapeType::mesh || s.type == spu::ShapeType::height_field;
      has_hull = has_hull || (!scene.bodies[i].is_static && s.type == spu::ShapeType::hull);
      for (const BodyInfo::Part& p : info[i].parts)
        has_hull = has_hull || scene.shapes[p.shape].type == spu::ShapeType::hull;
    }
    const bool hull_meets_mesh = has_mesh && has_hull;
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
      std::vector<dGeomID> parts;  // a compound's geoms, each with its pose about the body
      switch (s.type) {
        case spu::ShapeType::sphere:
        case spu::ShapeType::box:
        case spu::ShapeType::capsule:
        case spu::ShapeType::hull:
          geom = convex(s, sc, bi.hull_vertices, bi.hull_planes, bi.hull_faces);
          break;
        case spu::ShapeType::mesh:
        case spu::ShapeType::height_field: {
          // The dictionary's triangles (a height field's grid as cellphys triangulates it).
          if (!b.is_static) throw Unsupported("ODE: a triangle mesh on a dynamic body");
          if (hull_meets_mesh) throw Unsupported("ODE (built without libccd) has no convex-hull-to-triangle-mesh collider");
          tri_vertices_.push_back(std::make_unique<std::vector<dReal>>(bi.mesh_vertices.begin(), bi.mesh_vertices.end()));
          tri_indices_.push_back(std::make_unique<std::vector<dTriIndex>>(bi.mesh_triangles.begin(), bi.mesh_triangles.end()));
          dTriMeshDataID data = dGeomTriMeshDataCreate();
          dGeomTriMeshDataBuildDouble(data, tri_vertices_.back()->data(), 3 * sizeof(dReal),
                                      int(bi.mesh_vertices.size() / 3), tri_indices_.back()->data(),
                                      int(bi.mesh_triangles.size()), 3 * sizeof(dTriIndex));
          tri_data_.push_back(data);
          geom = dCreateTriMesh(space_, data, nullptr, nullptr, nullptr);
          break;
        }
        case spu::ShapeType::compound:
          for (const BodyInfo::Part& part : bi.parts) {
            dGeomID g = convex(scene.shapes[part.shape], part.scale, part.hull_vertices, part.hull_planes, part.hull_faces);
            if (!g) throw Unsupported("ODE: a compound part that is not convex");
            dGeomSetData(g, reinterpret_cast<void*>(i));
            parts.push_back(g);
          }
          geom = parts.front();
          break;
        case spu::ShapeType::plane: geom = dCreatePlane(space_, s.normal[0], s.normal[1], s.normal[2], s.offset); break;
      }
      geoms_[i] = geom;
      dGeomSetData(geom, reinterpret_cast<void*>(i));
      const dQuaternion q = {st.orientation[0], st.orientation[1], st.orientation[2], st.orientation[3]};
      if (s.type == spu::ShapeType::plane) continue;
      if (b.is_static) {
        if (parts.empty()) {
          dGeomSetPosition(geom, st.position[0], st.position[1], st.position[2]);
          dGeomSetQuaternion(geom, q);
        }
        for (size_t k = 0; k < parts.size(); ++k) {  // a static compound: each part's world pose
          const BodyInfo::Part& part = bi.parts[k];
          double bq[4] = {q[0], q[1], q[2], q[3]}, r[3], pq[4];
          const double n = std::sqrt(bq[0] * bq[0] + bq[1] * bq[1] + bq[2] * bq[2] + bq[3] * bq[3]);
          for (double& e : bq) e /= n;
          quat_rotate(bq, part.position, r);
          const double* o = part.orientation;
          pq[0] = bq[0] * o[0] - bq[1] * o[1] - bq[2] * o[2] - bq[3] * o[3];
          pq[1] = bq[0] * o[1] + bq[1] * o[0] + bq[2] * o[3] - bq[3] * o[2];
          pq[2] = bq[0] * o[2] - bq[1] * o[3] + bq[2] * o[0] + bq[3] * o[1];
          pq[3] = bq[0] * o[3] + bq[1] * o[2] - bq[2] * o[1] + bq[3] * o[0];
          const dQuaternion dq = {pq[0], pq[1], pq[2], pq[3]};
          dGeomSetPosition(parts[k], st.position[0] + r[0], st.position[1] + r[1], st.position[2] + r[2]);
          dGeomSetQuaternion(parts[k], dq);
        }
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
      if (parts.empty()) {
        dGeomSetBody(geom, body);
      } else {
        for (size_t k = 0; k < parts.size(); ++k) {
          const BodyInfo::Part& part = bi.parts[k];
          const dQuaternion pq = {part.orientation[0], part.orientation[1], part.orientation[2], part.orientation[3]};
          dGeomSetBody(parts[k], body);
          dGeomSetOffsetPosition(parts[k], part.position[0], part.position[1], part.position[2]);
          dGeomSetOffsetQuaternion(parts[k], pq);
        }
      }
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
    for (dTriMeshDataID d : tri_data_) dGeomTriMeshDataDestroy(d);
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
    if (b1 == b2) return;  // two parts of one compound
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
  std::vector<std::unique_ptr<std::vector<dReal>>> tri_vertices_;
  std::vector<std::unique_ptr<std::vector<dTriIndex>>> tri_indices_;
  std::vector<dTriMeshDataID> tri_data_;
  std::vector<State> states_;
  std::vector<double> wrench_;
};

}  // namespace

std::unique_ptr<Peer> make_ode(const scene::SceneDesc& scene, const EngineConfig& c) {
  return std::make_unique<OdePeer>(scene, c);
}

}  // namespace cellphys::bench
