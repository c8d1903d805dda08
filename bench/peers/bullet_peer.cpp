// Bullet (btDiscreteDynamicsWorld, sequential-impulse solver), z up with the scene's gravity.
// "default": Bullet's defaults (10 solver iterations); "tuned": more iterations (100 unless
// given). Friction: each body gets sqrt(mu) and Bullet multiplies the pair, giving the
// geometric mean. Inertia: the diagonal of the body-axes tensor (exact for spheres, boxes and
// capsules; hulls lose their products of inertia). Sleeping maps onto Bullet's deactivation.
// Joints: btPoint2Point, btHinge, btSlider, btFixed and btConeTwist constraints with Bullet's
// default softness and limit settings; a joint spring or damper, and a distance joint, are
// refused (those constraints have none; Bullet has no distance joint). Meshes and height
// fields: the cellphys triangles in a static btBvhTriangleMeshShape (two-sided, no internal-edge
// smoothing); compounds: btCompoundShape of the re-centred parts.
#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <memory>
#include <vector>

#include "bench/peers/common_checks.h"
#include "bench/peers/peer.h"

namespace cellphys::bench {
namespace {

// A joint frame at p: with axis_is_x, x along the axis and y along ref; otherwise z along the
// axis and x along ref (ref is perpendicular to the axis, both unit).
btTransform frame(const double p[3], const double axis[3], const double ref[3], bool axis_is_x) {
  const btVector3 n(axis[0], axis[1], axis[2]), u(ref[0], ref[1], ref[2]);
  const btVector3 x = axis_is_x ? n : u, y = axis_is_x ? u : n.cross(u), z = x.cross(y);
  btTransform t;
  t.setBasis(btMatrix3x3(x.x(), y.x(), z.x(), x.y(), y.y(), z.y(), x.z(), y.z(), z.z()));
  t.setOrigin(btVector3(p[0], p[1], p[2]));
  return t;
}

// A convex shape at a scale (a hull from its cellphys vertices, already scaled); nullptr for
// the others.
std::unique_ptr<btCollisionShape> convex(const scene::ShapeSpec& s, double sc, const std::vector<double>& hull_vertices) {
  switch (s.type) {
    case spu::ShapeType::sphere: return std::make_unique<btSphereShape>(s.radius * sc);
    case spu::ShapeType::box: {
      const btVector3 h(s.half_extents[0] * sc, s.half_extents[1] * sc, s.half_extents[2] * sc);
      auto box = std::make_unique<btBoxShape>(h);
      box->setMargin(std::min<btScalar>(0.04f, 0.2f * h[h.minAxis()]));
      return box;
    }
    case spu::ShapeType::capsule: return std::make_unique<btCapsuleShapeZ>(s.radius * sc, 2 * s.half_height * sc);
    case spu::ShapeType::hull: {
      auto hull = std::make_unique<btConvexHullShape>();
      for (size_t k = 0; k + 2 < hull_vertices.size(); k += 3)
        hull->addPoint(btVector3(hull_vertices[k], hull_vertices[k + 1], hull_vertices[k + 2]), false);
      hull->recalcLocalAabb();
      hull->setMargin(0.005f);
      return hull;
    }
    default: return nullptr;
  }
}

class BulletPeer : public Peer {
 public:
  BulletPeer(const scene::SceneDesc& scene, const EngineConfig& c) {
    check_forces(scene, "Bullet");
    const bool tuned = c.variant == "tuned";
    if (!c.variant.empty() && c.variant != "default" && !tuned)
      throw std::invalid_argument("bullet variants: default, tuned");
    dt_ = c.dt > 0 ? c.dt : scene.settings.dt;
    const std::vector<BodyInfo> info = body_info(scene);
    forces_ = std::make_unique<ExternalForces>(scene, info);
    config_ = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
    world_ = std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(), config_.get());
    const auto& g = scene.settings.globals.gravity;
    world_->setGravity(btVector3(g[0], g[1], g[2]));
    iterations_ = c.iterations > 0 ? c.iterations : tuned ? 100 : world_->getSolverInfo().m_numIterations;
    world_->getSolverInfo().m_numIterations = iterations_;
    label_ = std::string("bullet ") + (tuned ? "tuned" : "default") + " (" + std::to_string(iterations_) + " iterations)";
    gDeactivationTime = scene.settings.sleep_time;

    for (size_t i = 0; i < scene.bodies.size(); ++i) {
      const scene::BodySpec& b = scene.bodies[i];
      const ppe::BodyState& st = b.state;
      const BodyInfo& bi = info[i];
      const scene::ShapeSpec& s = scene.shapes[bi.shape];
      const double sc = b.scale;
      std::unique_ptr<btCollisionShape> shape;
      btTransform tr;
      tr.setIdentity();
      tr.setOrigin(btVector3(st.position[0], st.position[1], st.position[2]));
      tr.setRotation(btQuaternion(st.orientation[1], st.orientation[2], st.orientation[3], st.orientation[0]));
      switch (s.type) {
        case spu::ShapeType::sphere:
        case spu::ShapeType::box:
        case spu::ShapeType::capsule:
        case spu::ShapeType::hull: shape = convex(s, sc, bi.hull_vertices); break;
        case spu::ShapeType::mesh:
        case spu::ShapeType::height_field: {
          // The dictionary's triangles (a height field's grid as cellphys triangulates it) in
          // a btBvhTriangleMeshShape: static only, and two-sided where cellphys's are one-sided.
          if (!b.is_static) throw Unsupported("Bullet: a triangle mesh on a dynamic body");
          mesh_vertices_.push_back(std::make_unique<std::vector<btScalar>>(bi.mesh_vertices.begin(), bi.mesh_vertices.end()));
          mesh_indices_.push_back(std::make_unique<std::vector<int>>(bi.mesh_triangles.begin(), bi.mesh_triangles.end()));
          meshes_.push_back(std::make_unique<btTriangleIndexVertexArray>(
              int(bi.mesh_triangles.size() / 3), mesh_indices_.back()->data(), int(3 * sizeof(int)),
              int(bi.mesh_vertices.size() / 3), mesh_vertices_.back()->data(), int(3 * sizeof(btScalar))));
          shape = std::make_unique<btBvhTriangleMeshShape>(meshes_.back().get(), true);
          break;
        }
        case spu::ShapeType::compound: {
          // Each part at its pose about the compound's centre of mass (cellphys's re-centred parts).
          auto compound = std::make_unique<btCompoundShape>();
          for (const BodyInfo::Part& part : bi.parts) {
            auto child = convex(scene.shapes[part.shape], part.scale, part.hull_vertices);
            if (!child) throw Unsupported("Bullet: a compound part that is not convex");
            btTransform pt;
            pt.setOrigin(btVector3(part.position[0], part.position[1], part.position[2]));
            pt.setRotation(btQuaternion(part.orientation[1], part.orientation[2], part.orientation[3], part.orientation[0]));
            compound->addChildShape(pt, child.get());
            parts_.push_back(std::move(child));
          }
          shape = std::move(compound);
          break;
        }
        case spu::ShapeType::plane:
          shape = std::make_unique<btStaticPlaneShape>(btVector3(s.normal[0], s.normal[1], s.normal[2]), s.offset);
          tr.setIdentity();  // the plane is in world coordinates
          break;
      }
      const bool dynamic = !b.is_static && s.type != spu::ShapeType::plane;
      const btScalar mass = dynamic ? btScalar(bi.mass) : 0;
      const btVector3 inertia = dynamic ? btVector3(bi.inertia[0], bi.inertia[1], bi.inertia[2]) : btVector3(0, 0, 0);
      motion_.push_back(std::make_unique<btDefaultMotionState>(tr));
      btRigidBody::btRigidBodyConstructionInfo ci(mass, motion_.back().get(), shape.get(), inertia);
      ci.m_friction = std::sqrt(b.friction);
      ci.m_restitution = 0;
      auto body = std::make_unique<btRigidBody>(ci);
      if (dynamic) {
        body->setLinearVelocity(btVector3(st.velocity[0], st.velocity[1], st.velocity[2]));
        body->setAngularVelocity(btVector3(st.angular_velocity[0], st.angular_velocity[1], st.angular_velocity[2]));
        body->setSleepingThresholds(scene.settings.sleep_linear, scene.settings.sleep_angular);
        if (!scene.settings.sleeping) body->setActivationState(DISABLE_DEACTIVATION);
        dynamic_.push_back(body.get());
      }
      world_->addRigidBody(body.get());
      bodies_.push_back(std::move(body));
      shapes_.push_back(std::move(shape));
    }
    for (const JointSpec& j : scene_joints(scene)) {
      btRigidBody& ra = *bodies_[j.a];
      btRigidBody& rb = j.b < 0 ? btTypedConstraint::getFixedBody() : *bodies_[j.b];
      const btVector3 pa(j.pa[0], j.pa[1], j.pa[2]), pb(j.pb[0], j.pb[1], j.pb[2]);
      std::unique_ptr<btTypedConstraint> c;
      if ((j.type == "hinge" || j.type == "slider" || j.type == "cone_twist") && (j.spring_k > 0 || j.spring_c > 0))
        throw Unsupported("Bullet: its " + std::string(j.type == "hinge" ? "btHingeConstraint" : j.type == "slider"
                          ? "btSliderConstraint" : "btConeTwistConstraint") + " has no spring or damper (the " + j.type +
                          " has spring_stiffness or spring_damping)");
      if (j.type == "point_to_point") {
        c = std::make_unique<btPoint2PointConstraint>(ra, rb, pa, pb);
      } else if (j.type == "hinge") {
        // Frames with z along the axis and x along ref; referenced to A, Bullet's angle is B's x
        // from A's about A's z (cellphys's angle) and its motor drives that angle's rate.
        auto h = std::make_unique<btHingeConstraint>(ra, rb, frame(j.pa, j.axis_a, j.ref_a, false),
                                                     frame(j.pb, j.axis_b, j.ref_b, false), true);
        if (j.limited()) h->setLimit(j.lower, j.upper);
        if (j.motor_max > 0) h->enableAngularMotor(true, j.motor_speed, j.motor_max * dt_);  // an impulse a step
        c = std::move(h);
      } else if (j.type == "slider") {
        // Frames with x along the axis (Bullet slides along x) and y along ref; the travel is B's
        // origin from A's along A's x, as cellphys's; rotation about the axis is locked.
        auto sl = std::make_unique<btSliderConstraint>(ra, rb, frame(j.pa, j.axis_a, j.ref_a, true),
                                                       frame(j.pb, j.axis_b, j.ref_b, true), true);
        if (j.limited()) {
          sl->setLowerLinLimit(j.lower);
          sl->setUpperLinLimit(j.upper);
        } else {
          sl->setLowerLinLimit(1);  // lower above upper: free
          sl->setUpperLinLimit(-1);
        }
        sl->setLowerAngLimit(0);
        sl->setUpperAngLimit(0);
        if (j.motor_max > 0) {
          sl->setPoweredLinMotor(true);
          sl->setTargetLinMotorVelocity(j.motor_speed);
          sl->setMaxLinMotorForce(j.motor_max);
        }
        c = std::move(sl);
      } else if (j.type == "fixed") {
        c = std::make_unique<btFixedConstraint>(ra, rb, frame(j.pa, j.axis_a, j.ref_a, false),
                                                frame(j.pb, j.axis_b, j.ref_b, false));
      } else if (j.type == "cone_twist") {
        // Bullet twists about the frames' x; its twist limit is symmetric, so frame A is turned
        // about the axis to the middle of cellphys's twist range.
        const double mid = j.twist_limited() ? 0.5 * (j.twist_lower + j.twist_upper) : 0.0;
        btTransform fa = frame(j.pa, j.axis_a, j.ref_a, true);
        fa.setBasis(fa.getBasis() * btMatrix3x3(btQuaternion(btVector3(1, 0, 0), btScalar(mid))));
        auto ct = std::make_unique<btConeTwistConstraint>(ra, rb, fa, frame(j.pb, j.axis_b, j.ref_b, true));
        const btScalar free = BT_LARGE_FLOAT;
        const btScalar cone = j.cone_angle > 0 ? btScalar(j.cone_angle) : free;
        ct->setLimit(cone, cone, j.twist_limited() ? btScalar(0.5 * (j.twist_upper - j.twist_lower)) : free);
        c = std::move(ct);
      } else {
        // distance: a rope or rod holds |pb - pa| within bounds with both ends free to turn;
        // Bullet's joints hold frames along fixed axes (btGeneric6DofSpring2 limits each axis of
        // a box, not a radius), and btPoint2Point holds the points together.
        throw Unsupported("Bullet has no distance joint (rope or rod between two points free to turn); "
                          "btPoint2Point holds the points together and btGeneric6DofSpring2 limits box axes");
      }
      world_->addConstraint(c.get(), true);  // true: the joined pair does not collide, as in cellphys
      joints_.push_back(std::move(c));
    }
    states_.resize(scene.bodies.size());
  }
  ~BulletPeer() override {
    for (auto& j : joints_) world_->removeConstraint(j.get());
    for (auto& b : bodies_) world_->removeRigidBody(b.get());
  }
  void step() override {
    if (!forces_->empty()) {
      for (size_t i = 0; i < bodies_.size(); ++i) states_[i] = state(i);
      forces_->evaluate(states_, wrench_);
      for (size_t i = 0; i < bodies_.size(); ++i) {
        const double* f = &wrench_[6 * i];
        if (bodies_[i]->getInvMass() == 0) continue;
        bodies_[i]->applyCentralForce(btVector3(f[0], f[1], f[2]));
        bodies_[i]->applyTorque(btVector3(f[3], f[4], f[5]));
      }
    }
    world_->stepSimulation(btScalar(dt_), 0, btScalar(dt_));
  }
  State state(size_t i) const override {
    const btRigidBody& b = *bodies_[i];
    const btTransform& t = b.getCenterOfMassTransform();
    const btQuaternion q = t.getRotation();
    State s;
    for (int k = 0; k < 3; ++k)
      s.p[k] = t.getOrigin()[k], s.v[k] = b.getLinearVelocity()[k], s.w[k] = b.getAngularVelocity()[k];
    s.q[0] = q.w(), s.q[1] = q.x(), s.q[2] = q.y(), s.q[3] = q.z();
    return s;
  }
  long active_bodies() const override {
    long n = 0;
    for (const btRigidBody* b : dynamic_) n += b->isActive() ? 1 : 0;
    return n;
  }
  double last_iterations() const override { return iterations_; }
  std::string label() const override { return label_; }

 private:
  std::unique_ptr<ExternalForces> forces_;
  double dt_ = 0;
  int iterations_ = 10;
  std::string label_;
  std::unique_ptr<btDefaultCollisionConfiguration> config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btBroadphaseInterface> broadphase_;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
  std::unique_ptr<btDiscreteDynamicsWorld> world_;
  // Triangle data and compound parts outlive the shapes that use them (declared first).
  std::vector<std::unique_ptr<std::vector<btScalar>>> mesh_vertices_;
  std::vector<std::unique_ptr<std::vector<int>>> mesh_indices_;
  std::vector<std::unique_ptr<btTriangleIndexVertexArray>> meshes_;
  std::vector<std::unique_ptr<btCollisionShape>> parts_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btDefaultMotionState>> motion_;
  std::vector<std::unique_ptr<btRigidBody>> bodies_;
  std::vector<btRigidBody*> dynamic_;
  std::vector<std::unique_ptr<btTypedConstraint>> joints_;
  std::vector<State> states_;
  std::vector<double> wrench_;
};

}  // namespace

std::unique_ptr<Peer> make_bullet(const scene::SceneDesc& scene, const EngineConfig& c) {
  return std::make_unique<BulletPeer>(scene, c);
}

}  // namespace cellphys::bench
